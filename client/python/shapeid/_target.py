"""Client target strings as gRPC takes them: the Python twin of client/channel_target.cc
(ResolveChannelTarget), so that both clients accept the same targets."""

import dataclasses
import socket

# Schemes whose targets gRPC parses itself ("unix:" is not one: "unix:A,unix:B" is our list).
_GRPC_SCHEMES = ("dns:", "ipv4:", "ipv6:", "unix-abstract:", "xds:", "google-c2p:")


@dataclasses.dataclass(frozen=True)
class ChannelTarget:
    target: str            # what grpc gets
    authority: str = ""    # a list's first "HOST:PORT" (:authority, and TLS's name); "": gRPC's
    one_host: bool = True  # False: a TCP list naming several hosts (TLS needs tls_server_name)


def _has_scheme(text):
    return text.lower().startswith(_GRPC_SCHEMES)


def _bad(entry, index, why):
    return ValueError("target: entry %d '%s' %s" % (index + 1, entry, why))


def resolve(target):
    """`target` without a comma, or with a gRPC scheme, is one gRPC target, as it is.
    Otherwise a list "HOST:PORT,HOST:PORT,..." or "unix:PATH,unix:PATH,...": host names are
    looked up once and the list becomes "ipv4:..." / "ipv6:..." / "unix:...". ValueError
    naming the entry for a malformed one; ConnectionError when DNS does not answer."""
    if "," not in target or _has_scheme(target):
        return ChannelTarget(target)
    unix_paths, addresses = [], []
    first_host, authority, one_host = None, "", True
    for i, raw in enumerate(target.split(",")):
        entry = raw.strip()
        if not entry:
            raise _bad(entry, i, "is empty (a stray comma?)")
        bare_path = bool(unix_paths) and entry.startswith("/")
        is_unix = bare_path or entry.lower().startswith("unix:")
        if i > 0 and is_unix != bool(unix_paths):
            raise _bad(entry, i, "mixes a unix: socket with TCP endpoints; a list is all "
                                 "HOST:PORT or all unix:PATH")
        if is_unix:
            path = entry if bare_path else entry[5:]
            if path.startswith("//"):
                path = path[2:]
                if not path.startswith("/"):
                    raise _bad(entry, i, "names a host; a unix socket is unix:///ABSOLUTE or "
                                         "unix:PATH")
            if not path:
                raise _bad(entry, i, "has no path")
            unix_paths.append(path)
            continue
        if _has_scheme(entry):
            raise _bad(entry, i, "is a gRPC target of its own; a list holds HOST:PORT or "
                                 "unix:PATH entries (give a dns:/// target alone)")
        host, colon, port = entry.rpartition(":")
        if not colon:
            raise _bad(entry, i, "has no port (HOST:PORT)")
        if host.startswith("[") and host.endswith("]"):
            host = host[1:-1]
        elif ":" in host or "[" in host:
            raise _bad(entry, i, "has no port, or is an IPv6 address without brackets "
                                 "([::1]:PORT)")
        if not host:
            raise _bad(entry, i, "has no host")
        if not (port.isascii() and port.isdigit()) or not 1 <= int(port) <= 65535:
            raise _bad(entry, i, "has no port, or a bad one (HOST:PORT, PORT from 1 to 65535)")
        if i == 0:
            first_host, authority = host, entry
        elif host.lower() != first_host.lower():
            one_host = False
        addresses.extend(_lookup(entry, i, host, port))
    if unix_paths:
        return ChannelTarget("unix:" + ",".join(unix_paths))
    any_v6 = any(v6 for v6, _, _ in addresses)
    written = []
    for v6, host, port in addresses:
        if not any_v6:
            text = "%s:%s" % (host, port)
        else:
            text = "[%s%s]:%s" % ("" if v6 else "::ffff:", host, port)
        if text not in written:
            written.append(text)
    return ChannelTarget(("ipv6:" if any_v6 else "ipv4:") + ",".join(written), authority,
                         one_host)


def _lookup(entry, index, host, port):
    try:
        found = socket.getaddrinfo(host, port, socket.AF_UNSPEC, socket.SOCK_STREAM, 0,
                                   socket.AI_NUMERICSERV)
    except socket.gaierror as e:
        why = "cannot be resolved: %s" % e.strerror
        if e.errno in (socket.EAI_NONAME, socket.EAI_SERVICE, socket.EAI_FAMILY,
                       getattr(socket, "EAI_NODATA", None), getattr(socket, "EAI_ADDRFAMILY", None)):
            raise _bad(entry, index, why) from None
        raise ConnectionError("target: entry %d '%s' %s" % (index + 1, entry, why)) from None
    out = []
    for family, _, _, _, address in found:
        if family == socket.AF_INET:
            out.append((False, address[0], port))
        elif family == socket.AF_INET6:
            if address[3]:
                raise _bad(entry, index, "is a link-local IPv6 address with a zone; give it "
                                         "alone as ipv6:[ADDRESS%25ZONE]:PORT")
            out.append((True, address[0], port))
    return out
