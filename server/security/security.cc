#include "server/security/security.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/x509.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/strip.h"
#include "grpcpp/security/server_credentials.h"

namespace shapeid {
namespace {

// Certificates, keys and keys files are small; a larger "file" is a mistake (or /dev/zero).
constexpr size_t kMaxFileBytes = 1 << 20;

absl::StatusOr<std::string> ReadSmallFile(const std::string& path, absl::string_view what) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (f == nullptr) {
    const int error = errno;
    const std::string message =
        absl::StrCat("cannot read the ", what, " '", path, "': ", std::strerror(error));
    if (error == ENOENT) return absl::NotFoundError(message);
    if (error == EACCES) return absl::PermissionDeniedError(message);
    return absl::InvalidArgumentError(message);
  }
  std::string text;
  char buf[4096];
  size_t n;
  while ((n = std::fread(buf, 1, sizeof(buf), f)) > 0 && text.size() <= kMaxFileBytes) {
    text.append(buf, n);
  }
  const bool failed = std::ferror(f) != 0;
  std::fclose(f);
  if (failed)
    return absl::InvalidArgumentError(absl::StrCat("cannot read the ", what, " '", path, "'"));
  if (text.size() > kMaxFileBytes) {
    return absl::InvalidArgumentError(
        absl::StrCat("the ", what, " '", path, "' is larger than 1 MiB; is it the right file?"));
  }
  return text;
}

struct BioFree {
  void operator()(BIO* bio) const { BIO_free(bio); }
};
struct X509Free {
  void operator()(X509* x) const { X509_free(x); }
};
struct KeyFree {
  void operator()(EVP_PKEY* key) const { EVP_PKEY_free(key); }
};
using BioPtr = std::unique_ptr<BIO, BioFree>;
using X509Ptr = std::unique_ptr<X509, X509Free>;
using KeyPtr = std::unique_ptr<EVP_PKEY, KeyFree>;

BioPtr MemoryBio(const std::string& text) {
  return BioPtr(BIO_new_mem_buf(text.data(), static_cast<int>(text.size())));
}

// Never prompt on the terminal for a passphrase: an encrypted key is reported instead.
int NoPassphrase(char*, int, int, void*) { return 0; }

std::vector<X509Ptr> ReadCertificates(const std::string& pem) {
  std::vector<X509Ptr> certs;
  BioPtr bio = MemoryBio(pem);
  while (X509* cert = PEM_read_bio_X509(bio.get(), nullptr, NoPassphrase, nullptr)) {
    certs.emplace_back(cert);
  }
  ERR_clear_error();  // the loop ends on an error: no more certificates
  return certs;
}

absl::Status CheckServerPair(const std::string& cert_pem, const std::string& cert_path,
                             const std::string& key_pem, const std::string& key_path) {
  const std::vector<X509Ptr> chain = ReadCertificates(cert_pem);
  if (chain.empty()) {
    return absl::InvalidArgumentError(
        absl::StrCat("the TLS certificate file '", cert_path, "' holds no PEM certificate"));
  }
  BioPtr key_bio = MemoryBio(key_pem);
  KeyPtr key(PEM_read_bio_PrivateKey(key_bio.get(), nullptr, NoPassphrase, nullptr));
  ERR_clear_error();
  if (key == nullptr) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the TLS key file '", key_path,
        "' holds no PEM private key (an encrypted key is not supported: decrypt it with "
        "openssl pkey)"));
  }
  const bool match = X509_check_private_key(chain.front().get(), key.get()) == 1;
  ERR_clear_error();
  if (!match) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the key in '", key_path, "' does not match the certificate in '", cert_path, "'"));
  }
  if (X509_cmp_current_time(X509_get0_notAfter(chain.front().get())) < 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("the TLS certificate in '", cert_path, "' has expired"));
  }
  return absl::OkStatus();
}

// "HOST" of "HOST:PORT" or "[V6]:PORT", split as gRPC splits it: a bare IPv6 address (two
// colons or more, no brackets) is all host.
absl::string_view HostOf(absl::string_view listen) {
  if (absl::StartsWith(listen, "[")) {
    const size_t close = listen.find(']');
    return close == absl::string_view::npos ? listen : listen.substr(1, close - 1);
  }
  const size_t colon = listen.rfind(':');
  if (colon == absl::string_view::npos || listen.find(':') != colon) return listen;
  return listen.substr(0, colon);
}

// Whether `host` is a loopback address, when it is an IPv4 or IPv6 literal; nullopt for
// anything else (a name, "127.1", an empty host).
std::optional<bool> IsLoopbackLiteral(const std::string& host) {
  in_addr v4;
  if (inet_pton(AF_INET, host.c_str(), &v4) == 1) return (ntohl(v4.s_addr) >> 24) == 127;
  in6_addr v6;
  if (inet_pton(AF_INET6, host.c_str(), &v6) == 1) {
    return IN6_IS_ADDR_LOOPBACK(&v6) || (IN6_IS_ADDR_V4MAPPED(&v6) && v6.s6_addr[12] == 127);
  }
  return std::nullopt;
}

// Whether `listen` is local (IsLoopbackAddress) and, for a host name, what it resolved to.
struct Reach {
  bool local = false;
  std::string resolved;  // empty unless the host is a name
};

Reach ReachOf(absl::string_view listen, const HostResolver& resolve) {
  if (absl::StartsWith(listen, "unix:") || absl::StartsWith(listen, "unix-abstract:")) {
    return {true, ""};
  }
  const std::string host(HostOf(listen));
  if (host.empty()) return {false, ""};  // every interface
  if (std::optional<bool> loopback = IsLoopbackLiteral(host)) return {*loopback, ""};
  // A name, or a number inet_pton does not read ("127.1"): what gRPC will bind.
  const absl::StatusOr<std::vector<std::string>> addresses = resolve(host);
  if (!addresses.ok()) return {false, std::string(addresses.status().message())};
  const bool local = !addresses->empty() &&
                     std::all_of(addresses->begin(), addresses->end(), [](const std::string& a) {
                       return IsLoopbackLiteral(a).value_or(false);
                     });
  return {local, absl::StrCat(host, " resolves to ", absl::StrJoin(*addresses, ", "))};
}

}  // namespace

absl::StatusOr<std::vector<std::string>> ResolveListenHost(const std::string& host) {
  addrinfo hints = {};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_PASSIVE;
  addrinfo* found = nullptr;
  const int error = getaddrinfo(host.c_str(), nullptr, &hints, &found);
  if (error != 0) {
    const std::string message = absl::StrCat("cannot resolve ", host, ": ", gai_strerror(error));
    return error == EAI_AGAIN ? absl::UnavailableError(message) : absl::NotFoundError(message);
  }
  std::vector<std::string> addresses;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    char text[INET6_ADDRSTRLEN] = "";
    const void* address = nullptr;
    if (a->ai_family == AF_INET) {
      address = &reinterpret_cast<const sockaddr_in*>(a->ai_addr)->sin_addr;
    } else if (a->ai_family == AF_INET6) {
      address = &reinterpret_cast<const sockaddr_in6*>(a->ai_addr)->sin6_addr;
    }
    // Another family is kept as a name no literal check accepts: it is not loopback.
    std::string entry = address != nullptr && inet_ntop(a->ai_family, address, text, sizeof(text))
                            ? std::string(text)
                            : absl::StrCat("an address of family ", a->ai_family);
    if (std::find(addresses.begin(), addresses.end(), entry) == addresses.end()) {
      addresses.push_back(std::move(entry));
    }
  }
  freeaddrinfo(found);
  if (addresses.empty()) return absl::NotFoundError(absl::StrCat(host, " has no address"));
  return addresses;
}

bool IsLoopbackAddress(absl::string_view listen, const HostResolver& resolve) {
  return ReachOf(listen, resolve).local;
}

absl::StatusOr<std::shared_ptr<const ApiKeyStore>> LoadApiKeys(const SecurityOptions& security) {
  std::vector<ApiKeyEntry> all;
  const auto add = [&all](const std::string& text, const std::string& source) -> absl::Status {
    absl::StatusOr<std::vector<ApiKeyEntry>> keys = ParseApiKeys(text, source);
    if (!keys.ok()) return keys.status();
    if (keys->empty()) {
      return absl::InvalidArgumentError(absl::StrCat(
          source, " holds no API key; give at least one, or leave it out to run without keys"));
    }
    for (ApiKeyEntry& key : *keys) all.push_back(std::move(key));
    return absl::OkStatus();
  };
  if (!security.api_keys_file.empty()) {
    absl::StatusOr<std::string> text = ReadSmallFile(security.api_keys_file, "API keys file");
    if (!text.ok()) return text.status();
    if (absl::Status s = add(*text, security.api_keys_file); !s.ok()) return s;
  }
  if (!security.api_keys.empty()) {
    if (absl::Status s = add(security.api_keys, "--api_keys (SHAPEID_API_KEYS)"); !s.ok()) return s;
  }
  absl::StatusOr<ApiKeyStore> store = ApiKeyStore::Create(std::move(all));
  if (!store.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "API keys (--api_keys_file and --api_keys together): ", store.status().message()));
  }
  return std::make_shared<const ApiKeyStore>(*std::move(store));
}

absl::StatusOr<std::shared_ptr<grpc::ServerCredentials>> ListeningCredentials(
    const SecurityOptions& security) {
  const bool tls = !security.tls_cert_file.empty() || !security.tls_key_file.empty();
  if (!tls) {
    if (!security.tls_client_ca_file.empty()) {
      return absl::InvalidArgumentError(
          "--tls_client_ca needs --tls_cert and --tls_key: client certificates are checked "
          "only on TLS connections");
    }
    return grpc::InsecureServerCredentials();
  }
  if (security.tls_cert_file.empty() || security.tls_key_file.empty()) {
    return absl::InvalidArgumentError("give both --tls_cert and --tls_key, or neither");
  }
  absl::StatusOr<std::string> cert = ReadSmallFile(security.tls_cert_file, "TLS certificate file");
  if (!cert.ok()) return cert.status();
  absl::StatusOr<std::string> key = ReadSmallFile(security.tls_key_file, "TLS key file");
  if (!key.ok()) return key.status();
  if (absl::Status s = CheckServerPair(*cert, security.tls_cert_file, *key, security.tls_key_file);
      !s.ok()) {
    return s;
  }
  grpc::SslServerCredentialsOptions options(GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE);
  if (!security.tls_client_ca_file.empty()) {
    absl::StatusOr<std::string> ca =
        ReadSmallFile(security.tls_client_ca_file, "TLS client CA file");
    if (!ca.ok()) return ca.status();
    if (ReadCertificates(*ca).empty()) {
      return absl::InvalidArgumentError(absl::StrCat(
          "the TLS client CA file '", security.tls_client_ca_file, "' holds no PEM certificate"));
    }
    options.pem_root_certs = *std::move(ca);
    options.client_certificate_request = GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY;
  }
  options.pem_key_cert_pairs.push_back({*std::move(key), *std::move(cert)});
  return grpc::SslServerCredentials(options);
}

absl::Status CheckExposure(absl::string_view listen, const SecurityOptions& security, bool has_keys,
                           const HostResolver& resolve) {
  const bool tls = !security.tls_cert_file.empty();
  if (tls || has_keys || security.insecure) return absl::OkStatus();
  const Reach reach = ReachOf(listen, resolve);
  if (reach.local) return absl::OkStatus();
  return absl::FailedPreconditionError(absl::StrCat(
      "refusing to listen on ", listen,
      reach.resolved.empty() ? ""
                             : absl::StrCat(" (", reach.resolved,
                                            "; a name counts as local only if every address "
                                            "it resolves to is loopback)"),
      " with neither TLS nor API keys: anyone who can reach it could read, train and delete "
      "galleries. Give --api_keys_file (and --tls_cert/--tls_key; see docs/security.md), or "
      "--insecure to run it open on purpose"));
}

std::vector<std::string> SecurityWarnings(absl::string_view listen, const SecurityOptions& security,
                                          const ApiKeyStore& keys) {
  std::vector<std::string> warnings;
  if (IsLoopbackAddress(listen)) return warnings;
  const bool tls = !security.tls_cert_file.empty();
  if (!tls && !keys.empty()) {
    warnings.push_back(absl::StrCat("API keys cross the network in plaintext on ", listen,
                                    "; add --tls_cert and --tls_key"));
  } else if (keys.empty() && security.tls_client_ca_file.empty()) {
    warnings.push_back(absl::StrCat("no API keys on ", listen,
                                    ": every client that reaches it may train, delete and import",
                                    tls ? "" : " (--insecure)"));
  }
  return warnings;
}

std::string DescribeSecurity(const SecurityOptions& security, const ApiKeyStore& keys) {
  std::string line;
  if (security.tls_cert_file.empty()) {
    line = "plaintext (no TLS)";
  } else if (security.tls_client_ca_file.empty()) {
    line = "TLS";
  } else {
    line = "TLS with client certificates (mutual TLS)";
  }
  if (keys.empty()) {
    absl::StrAppend(&line, ", no API keys: every caller may call everything");
  } else {
    absl::StrAppend(&line, ", ", keys.size(), keys.size() == 1 ? " API key (" : " API keys (",
                    keys.CountWithScope(Scope::kRead), " read, ",
                    keys.CountWithScope(Scope::kWrite), " write, ",
                    keys.CountWithScope(Scope::kAdmin),
                    " admin); health checks and reflection need none");
  }
  return line;
}

}  // namespace shapeid
