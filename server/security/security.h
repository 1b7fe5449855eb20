#ifndef SHAPEID_SERVER_SECURITY_SECURITY_H_
#define SHAPEID_SERVER_SECURITY_SECURITY_H_

// From SecurityOptions to what the server runs with: its listening credentials, its API
// keys, and the start-up rules (docs/security.md).

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "grpcpp/security/server_credentials.h"
#include "server/security/api_keys.h"
#include "server/security/security_options.h"

namespace shapeid {

// The addresses a host name resolves to for listening, as text ("127.0.0.1", "::1"):
// getaddrinfo, as gRPC resolves an address to listen on (/etc/hosts, then DNS; may block on
// DNS). NotFound, or Unavailable for a temporary DNS failure, with getaddrinfo's reason.
absl::StatusOr<std::vector<std::string>> ResolveListenHost(const std::string& host);

// How the checks below resolve host names: ResolveListenHost, or a stand-in in tests.
using HostResolver = std::function<absl::StatusOr<std::vector<std::string>>(const std::string&)>;

// True when `listen` (HOST:PORT, [V6]:PORT, unix:PATH or unix-abstract:NAME) is reachable
// from this machine only: a Unix socket; an address in 127.0.0.0/8, ::1 or
// ::ffff:127.0.0.0/104; or a host name of which every address `resolve` gives is one of those,
// so a "localhost" that /etc/hosts maps elsewhere, or a name that does not resolve, is not.
// False for every interface ("0.0.0.0", "[::]", an empty host).
bool IsLoopbackAddress(absl::string_view listen, const HostResolver& resolve = ResolveListenHost);

// The API keys of `security` (its file, then its inline text), in one store; empty when
// neither is given. InvalidArgument naming the file and line of a malformed entry, a
// duplicate, or a file or text with no key at all; NotFound / PermissionDenied for a file
// that cannot be read.
absl::StatusOr<std::shared_ptr<const ApiKeyStore>> LoadApiKeys(const SecurityOptions& security);

// TLS server credentials from the files of `security`, checked first with OpenSSL: each
// readable and PEM, the key matching the certificate, the certificate not expired, a client
// CA file holding at least one certificate. Insecure credentials when no file is given.
// InvalidArgument naming the file and the problem.
absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> ListeningCredentials(
    const SecurityOptions& security);

// FailedPrecondition when a server would listen on a non-loopback `listen`
// (IsLoopbackAddress) with neither TLS nor API keys (`has_keys`) and without
// `security.insecure`. The message is one line, what shapeid-server prints before it exits 2;
// for a host name it says what the name resolved to.
absl::Status CheckExposure(absl::string_view listen, const SecurityOptions& security, bool has_keys,
                           const HostResolver& resolve = ResolveListenHost);

// What the start-up log should warn about in a configuration that starts but is weaker than
// it may look: API keys in plaintext on a network address; a network address without keys
// (and without client certificates). One line each; never a key or digest.
std::vector<std::string> SecurityWarnings(absl::string_view listen, const SecurityOptions& security,
                                          const ApiKeyStore& keys);

// One line for the start-up log: "TLS with client certificates, 3 API keys (1 read, 1
// write, 1 admin)". Never a key or digest.
std::string DescribeSecurity(const SecurityOptions& security, const ApiKeyStore& keys);

}  // namespace shapeid

#endif  // SHAPEID_SERVER_SECURITY_SECURITY_H_
