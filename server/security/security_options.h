#ifndef SHAPEID_SERVER_SECURITY_SECURITY_OPTIONS_H_
#define SHAPEID_SERVER_SECURITY_SECURITY_OPTIONS_H_

#include <string>

namespace shapeid {

// Transport security and API keys of a server (docs/security.md). All empty, the default: a
// plaintext server open to every client, which ShapeIdServer::Bind accepts only on a
// loopback address (or with `insecure`).
struct SecurityOptions {
  // PEM files of the server's certificate (chain) and private key. Both or neither; with
  // them the server speaks only TLS. Checked at start-up (readable, PEM, the key matches the
  // certificate, not expired), so a bad file is named there rather than at the first
  // handshake.
  std::string tls_cert_file;
  std::string tls_key_file;
  // PEM file of the CA certificates that sign client certificates. Given: mutual TLS, every
  // client must present a certificate that verifies against it. Needs tls_cert_file.
  std::string tls_client_ca_file;

  // API keys (server/security/api_keys.h): a keys file, and/or the same format inline (entries
  // separated by newlines or ';', as an environment variable can carry them). Given, every
  // call but health checks needs a key with the method's scope. A file or text that holds
  // no key is an error, not an open server.
  std::string api_keys_file;
  std::string api_keys;

  // Listen on a non-loopback address with neither TLS nor API keys: anyone who can reach
  // the port may read, train and delete. Off by default, when such a server refuses to start.
  bool insecure = false;
};

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SECURITY_SECURITY_OPTIONS_H_
