#ifndef SHAPEID_CLIENT_CHANNEL_TARGET_H_
#define SHAPEID_CLIENT_CHANNEL_TARGET_H_

// ClientOptions::target as gRPC 1.51 takes it. Internal to the client library (not installed).

#include <string>

#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"

namespace shapeid {

struct ChannelTarget {
  // What grpc::CreateCustomChannel gets.
  std::string target;
  // For a list: the first entry's "HOST:PORT", to send as :authority and, with TLS, the name
  // the certificate is checked against (gRPC would otherwise use the whole list). Empty:
  // gRPC's own default for `target`.
  std::string authority;
  // For a list of TCP entries: false when they name more than one host (a TLS channel checks
  // one name for every replica, so it then needs ClientOptions::tls_server_name).
  bool one_host = true;
};

// `target` without a comma, or starting with a gRPC scheme other than unix ("dns:",
// "ipv4:", "ipv6:", "unix-abstract:", "xds:"), is one gRPC target: returned as it is, but
// for kDefaultPort added to a host without a port ("127.0.0.1", "[::1]", "::1", "localhost",
// "dns:///NAME"; a bare IPv6 address is all host).
// Otherwise it is a list of endpoints, "HOST:PORT,HOST:PORT,..." (an entry without a port
// gets kDefaultPort) or "unix:PATH,unix:PATH,..."
// (or gRPC's own "unix:/A,/B"; blanks around entries ignored), turned into one target that
// resolves to all of them: "ipv4:A:P,B:P" when every address is IPv4, else
// "ipv6:[...]:P,..." with the IPv4 ones v4-mapped (gRPC connects to those over IPv4), or
// "unix:PATH,PATH". Host names are looked up here, once (getaddrinfo; every address of a name
// is an endpoint): a set of replicas that changes belongs behind one DNS name given as
// "dns:///NAME:PORT", which gRPC re-resolves. InvalidArgument, naming the entry, for an
// empty entry, a bad port, colons that make neither HOST:PORT nor an IPv6 address, unix entries
// mixed with TCP ones, or a name that does not exist; Unavailable when the lookup itself fails (no
// answer from DNS: EAI_AGAIN and the like).
absl::StatusOr<ChannelTarget> ResolveChannelTarget(absl::string_view target);

}  // namespace shapeid

#endif  // SHAPEID_CLIENT_CHANNEL_TARGET_H_
