"""The client's channel: target strings as gRPC takes them (the Python twin of
client/channel_target.cc, so that both clients accept the same targets), balancing and
credentials as client/client.cc's MakeChannel sets them."""

import dataclasses
import json
import socket

import grpc

# The largest answer the client reads by default, in bytes: the C++ client's
# kClientMaxReceiveBytes (client/client_options.h), 256 MiB, the most a server's
# --max_answer_bytes may be, so every answer of a shapeid server can be read.
MAX_RECEIVE_BYTES = 256 << 20

# The port a host without one gets: shapeid-server's default (kDefaultPort).
DEFAULT_PORT = 50051

# Schemes whose targets gRPC parses itself ("unix:" is not one: "unix:A,unix:B" is our list).
_GRPC_SCHEMES = ("dns:", "ipv4:", "ipv6:", "unix-abstract:", "xds:", "google-c2p:")


@dataclasses.dataclass(frozen=True)
class ChannelTarget:
    target: str            # what grpc gets
    authority: str = ""    # a list's first "HOST:PORT" (:authority, and TLS's name); "": gRPC's
    one_host: bool = True  # False: a TCP list naming several hosts (TLS needs tls_server_name)


def _has_scheme(text):
    return text.lower().startswith(_GRPC_SCHEMES)


def _with_default_port(host_port):
    """"HOST", "[V6]" or a bare "V6" address with ":DEFAULT_PORT" added; anything else (a port
    is there, or it is no host) as it is. A bare IPv6 address is all host, as gRPC reads it."""
    if not host_port:
        return host_port
    if host_port.startswith("["):
        return "%s:%d" % (host_port, DEFAULT_PORT) if host_port.endswith("]") else host_port
    colons = host_port.count(":")
    if colons == 0:
        return "%s:%d" % (host_port, DEFAULT_PORT)
    if colons >= 2:
        try:
            socket.inet_pton(socket.AF_INET6, host_port)
        except (OSError, ValueError):
            return host_port
        return "[%s]:%d" % (host_port, DEFAULT_PORT)
    return host_port


def _one_target(target):
    """One gRPC target with DEFAULT_PORT where a host has no port: a plain HOST and a dns:
    target's host (gRPC's DNS resolver would otherwise use 443). Other schemes as they are."""
    if target.lower().startswith("dns:"):
        start = 4  # dns:[//AUTHORITY/]HOST[:PORT]
        if target[4:].startswith("//"):
            slash = target.find("/", 6)
            if slash < 0:
                return target
            start = slash + 1
        return target[:start] + _with_default_port(target[start:])
    if _has_scheme(target) or target.lower().startswith("unix:") or "://" in target:
        return target
    return _with_default_port(target)


def _bad(entry, index, why):
    return ValueError("target: entry %d '%s' %s" % (index + 1, entry, why))


def resolve(target):
    """`target` without a comma, or with a gRPC scheme, is one gRPC target, as it is but for
    DEFAULT_PORT added to a host without a port ("127.0.0.1", "[::1]", "::1", "localhost",
    "dns:///NAME"). Otherwise a list "HOST[:PORT],HOST[:PORT],..." or
    "unix:PATH,unix:PATH,...": host names are looked up once and the list becomes
    "ipv4:..." / "ipv6:..." / "unix:...". ValueError naming the entry for a malformed one;
    ConnectionError when DNS does not answer."""
    if "," not in target or _has_scheme(target):
        return ChannelTarget(_one_target(target))
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
        host_port = _with_default_port(entry)
        host, colon, port = host_port.rpartition(":")
        if not colon:
            raise _bad(entry, i, "has no port (HOST:PORT)")
        if host.startswith("[") and host.endswith("]"):
            host = host[1:-1]
        elif ":" in host or "[" in host:
            raise _bad(entry, i, "is neither HOST[:PORT] nor an IPv6 address (with a port: "
                                 "[::1]:PORT)")
        if not host:
            raise _bad(entry, i, "has no host")
        if not (port.isascii() and port.isdigit()) or not 1 <= int(port) <= 65535:
            raise _bad(entry, i, "has no port, or a bad one (HOST:PORT, PORT from 1 to 65535)")
        if i == 0:
            first_host, authority = host, host_port
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


def _read_pem(path, what):
    try:
        with open(path, "rb") as f:
            text = f.read(1 << 20)
    except OSError as e:
        raise ValueError("cannot read the %s '%s': %s" % (what, path, e.strerror)) from None
    if b"-----BEGIN " not in text:
        raise ValueError("the %s '%s' is not a PEM file" % (what, path))
    return text


def make_channel(target, load_balancing, tls, ca_file, cert_file, key_file, server_name,
                 max_receive_bytes=MAX_RECEIVE_BYTES):
    """A grpc channel for the Client's options; ValueError for a bad combination."""
    resolved = resolve(target)
    replicas = "," in target or target.startswith("dns:")
    if load_balancing == "round_robin" and replicas:
        # healthCheckConfig: replicas that are loading or draining (NOT_SERVING) get no calls.
        config = {"loadBalancingConfig": [{"round_robin": {}}],
                  "healthCheckConfig": {"serviceName": ""}}
    elif load_balancing in ("round_robin", "pick_first"):
        config = {"loadBalancingConfig": [{load_balancing: {}}]}
    else:
        raise ValueError("load_balancing must be round_robin or pick_first, got %r"
                         % (load_balancing,))
    options = [("grpc.service_config", json.dumps(config)),
               ("grpc.max_receive_message_length", max_receive_bytes)]
    if resolved.authority:
        options.append(("grpc.default_authority", resolved.authority))
    tls = tls or bool(ca_file or cert_file or key_file)
    if not tls:
        if server_name:
            raise ValueError("tls_server_name is set but TLS is off")
        return grpc.insecure_channel(resolved.target, options=options)
    if not resolved.one_host and not server_name:
        raise ValueError("target '%s' lists replicas on different hosts and TLS checks one name "
                         "for all of them: set tls_server_name to a name every replica's "
                         "certificate carries" % target)
    if bool(cert_file) != bool(key_file):
        raise ValueError("a client certificate needs its key, and a key its certificate: give "
                         "both TLS files or neither")
    credentials = grpc.ssl_channel_credentials(
        root_certificates=_read_pem(ca_file, "TLS CA file") if ca_file else None,
        private_key=_read_pem(key_file, "TLS client key file") if key_file else None,
        certificate_chain=_read_pem(cert_file, "TLS client certificate file") if cert_file
        else None)
    if server_name:
        options.append(("grpc.ssl_target_name_override", server_name))
    return grpc.secure_channel(resolved.target, credentials, options=options)

