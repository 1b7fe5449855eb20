#include "client/channel_target.h"

#include <arpa/inet.h>
#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <algorithm>
#include <iterator>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "client/client_options.h"

namespace shapeid {
namespace {

// Schemes whose targets gRPC 1.51 parses itself (a comma in them is gRPC's business: "ipv4:"
// and "ipv6:" take lists). "unix:" is not here: "unix:A,unix:B" is our list of sockets.
constexpr absl::string_view kGrpcSchemes[] = {
    "dns:", "ipv4:", "ipv6:", "unix-abstract:", "xds:", "google-c2p:"};

bool HasGrpcScheme(absl::string_view text) {
  return std::any_of(
      std::begin(kGrpcSchemes), std::end(kGrpcSchemes),
      [&](absl::string_view scheme) { return absl::StartsWithIgnoreCase(text, scheme); });
}

// "HOST", "[V6]" or a bare "V6" address with ":kDefaultPort" added; anything else (a port is
// there, or it is no host) as it is. A bare IPv6 address is all host, as gRPC reads it.
std::string WithDefaultPort(absl::string_view host_port) {
  if (host_port.empty()) return std::string(host_port);
  const size_t colons = std::count(host_port.begin(), host_port.end(), ':');
  bool add = false;
  std::string host(host_port);
  if (absl::StartsWith(host_port, "[")) {
    add = absl::EndsWith(host_port, "]");
  } else if (colons == 0) {
    add = true;
  } else if (colons >= 2) {
    in6_addr address;
    add = ::inet_pton(AF_INET6, host.c_str(), &address) == 1;
    if (add) host = absl::StrCat("[", host, "]");
  }
  return add ? absl::StrCat(host, ":", kDefaultPort) : std::string(host_port);
}

// One target as gRPC takes it, with kDefaultPort where a host has no port: a plain HOST and
// a dns: target's host (gRPC's DNS resolver would otherwise use 443). Other schemes as they
// are.
std::string OneTargetWithDefaultPort(absl::string_view target) {
  if (absl::StartsWithIgnoreCase(target, "dns:")) {
    // dns:[//AUTHORITY/]HOST[:PORT]
    absl::string_view rest = target.substr(4);
    size_t host_start = 4;
    if (absl::StartsWith(rest, "//")) {
      const size_t slash = rest.find('/', 2);
      if (slash == absl::string_view::npos) return std::string(target);
      host_start += slash + 1;
    }
    return absl::StrCat(target.substr(0, host_start), WithDefaultPort(target.substr(host_start)));
  }
  if (HasGrpcScheme(target) || absl::StartsWithIgnoreCase(target, "unix:") ||
      absl::StrContains(target, "://")) {
    return std::string(target);
  }
  return WithDefaultPort(target);
}

absl::Status BadEntry(absl::string_view entry, size_t index, absl::string_view why) {
  return absl::InvalidArgumentError(
      absl::StrCat("ClientOptions.target: entry ", index + 1, " '", entry, "' ", why));
}

// One TCP address as the "ipv4:" or "ipv6:" resolver reads it.
struct Address {
  bool v6 = false;
  std::string host;  // numeric, without brackets
  std::string port;
};

// The addresses of `host` (a literal or a name), in getaddrinfo's order (RFC 6724).
absl::Status Lookup(absl::string_view entry, size_t index, const std::string& host,
                    const std::string& port, std::vector<Address>& out) {
  addrinfo hints = {};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_STREAM;
  hints.ai_flags = AI_NUMERICSERV;
  addrinfo* found = nullptr;
  const int error = ::getaddrinfo(host.c_str(), port.c_str(), &hints, &found);
  if (error != 0) {
    const std::string why = absl::StrCat("cannot be resolved: ", ::gai_strerror(error));
    // A name that does not exist is a mistake in the target; anything else (no answer from
    // DNS) may pass, so the caller can try again later.
    if (error == EAI_NONAME || error == EAI_SERVICE || error == EAI_FAMILY
#ifdef EAI_NODATA
        || error == EAI_NODATA
#endif
#ifdef EAI_ADDRFAMILY
        || error == EAI_ADDRFAMILY
#endif
    ) {
      return BadEntry(entry, index, why);
    }
    return absl::UnavailableError(
        absl::StrCat("ClientOptions.target: entry ", index + 1, " '", entry, "' ", why));
  }
  absl::Status status;
  for (const addrinfo* a = found; a != nullptr; a = a->ai_next) {
    char text[INET6_ADDRSTRLEN] = {};
    Address address;
    address.port = port;
    if (a->ai_family == AF_INET) {
      ::inet_ntop(AF_INET, &reinterpret_cast<const sockaddr_in*>(a->ai_addr)->sin_addr, text,
                  sizeof(text));
    } else if (a->ai_family == AF_INET6) {
      const auto* in6 = reinterpret_cast<const sockaddr_in6*>(a->ai_addr);
      if (in6->sin6_scope_id != 0) {
        // gRPC wants the zone as an interface name inside the URI: not worth the escaping.
        status = BadEntry(entry, index,
                          "is a link-local IPv6 address with a zone; give it alone as "
                          "ipv6:[ADDRESS%25ZONE]:PORT");
        break;
      }
      ::inet_ntop(AF_INET6, &in6->sin6_addr, text, sizeof(text));
      address.v6 = true;
    } else {
      continue;
    }
    address.host = text;
    out.push_back(std::move(address));
  }
  ::freeaddrinfo(found);
  return status;
}

}  // namespace

absl::StatusOr<ChannelTarget> ResolveChannelTarget(absl::string_view target) {
  ChannelTarget result;
  if (!absl::StrContains(target, ',') || HasGrpcScheme(target)) {
    result.target = OneTargetWithDefaultPort(target);
    return result;
  }
  const std::vector<absl::string_view> entries = absl::StrSplit(target, ',');
  std::vector<std::string> unix_paths;
  std::vector<Address> addresses;
  std::string first_host;
  for (size_t i = 0; i < entries.size(); ++i) {
    const absl::string_view entry = absl::StripAsciiWhitespace(entries[i]);
    if (entry.empty()) return BadEntry(entry, i, "is empty (a stray comma?)");
    // After a unix: entry, a bare absolute path is one too: gRPC's own "unix:/a,/b" form.
    const bool bare_path = !unix_paths.empty() && absl::StartsWith(entry, "/");
    const bool is_unix = bare_path || absl::StartsWithIgnoreCase(entry, "unix:");
    if (i > 0 && is_unix != !unix_paths.empty()) {
      return BadEntry(entry, i,
                      "mixes a unix: socket with TCP endpoints; a list is all HOST:PORT or all "
                      "unix:PATH");
    }
    if (is_unix) {
      absl::string_view path = bare_path ? entry : entry.substr(5);
      if (absl::StartsWith(path, "//")) {
        path.remove_prefix(2);  // "unix:///abs": an empty authority, then the path
        if (!absl::StartsWith(path, "/")) {
          return BadEntry(entry, i, "names a host; a unix socket is unix:///ABSOLUTE or unix:PATH");
        }
      }
      if (path.empty()) return BadEntry(entry, i, "has no path");
      unix_paths.emplace_back(path);
      continue;
    }
    if (HasGrpcScheme(entry)) {
      return BadEntry(entry, i,
                      "is a gRPC target of its own; a list holds HOST:PORT or unix:PATH entries "
                      "(give a dns:/// target alone)");
    }
    const std::string host_port = WithDefaultPort(entry);
    const size_t colon = host_port.rfind(':');
    if (colon == std::string::npos) return BadEntry(entry, i, "has no port (HOST:PORT)");
    absl::string_view host = absl::string_view(host_port).substr(0, colon);
    const absl::string_view port = absl::string_view(host_port).substr(colon + 1);
    if (absl::StartsWith(host, "[") && absl::EndsWith(host, "]")) {
      host = host.substr(1, host.size() - 2);
    } else if (absl::StrContains(host, ':') || absl::StrContains(host, '[')) {
      return BadEntry(entry, i,
                      "is neither HOST[:PORT] nor an IPv6 address (with a port: [::1]:PORT)");
    }
    if (host.empty()) return BadEntry(entry, i, "has no host");
    int port_number = 0;
    if (port.empty() || !std::all_of(port.begin(), port.end(), absl::ascii_isdigit) ||
        !absl::SimpleAtoi(port, &port_number) || port_number < 1 || port_number > 65535) {
      return BadEntry(entry, i, "has no port, or a bad one (HOST:PORT, PORT from 1 to 65535)");
    }
    if (i == 0) {
      first_host = std::string(host);
      result.authority = host_port;
    } else if (!absl::EqualsIgnoreCase(host, first_host)) {
      result.one_host = false;
    }
    absl::Status looked_up = Lookup(entry, i, std::string(host), std::string(port), addresses);
    if (!looked_up.ok()) return looked_up;
  }
  if (!unix_paths.empty()) {
    result.target = absl::StrCat("unix:", absl::StrJoin(unix_paths, ","));
    return result;
  }
  // The same address twice (a name and its literal) would only weigh that replica double.
  std::vector<std::string> written;
  const bool any_v6 =
      std::any_of(addresses.begin(), addresses.end(), [](const Address& a) { return a.v6; });
  for (const Address& a : addresses) {
    std::string text;
    if (!any_v6) {
      text = absl::StrCat(a.host, ":", a.port);
    } else {
      text = absl::StrCat("[", a.v6 ? "" : "::ffff:", a.host, "]:", a.port);
    }
    if (std::find(written.begin(), written.end(), text) == written.end()) {
      written.push_back(std::move(text));
    }
  }
  result.target = absl::StrCat(any_v6 ? "ipv6:" : "ipv4:", absl::StrJoin(written, ","));
  return result;
}

}  // namespace shapeid
