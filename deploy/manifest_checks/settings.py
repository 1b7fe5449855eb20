"""The server's settings (SHAPEID_*) as both compose and Kubernetes give them: which exist (read
from server/main.cc), their allowed values, the listen and metrics ports, the store URI."""

import re

# The server's settings: SHAPEID_<FLAG> for every ABSL_FLAG in server/main.cc (read there, so a
# new flag needs no change here). Empty until read_server_settings finds the file: a deploy
# folder checked on its own has no list to check its settings against.
SERVER_SETTINGS = set()
# The settings that only the PostgreSQL variants have.
STORE_SETTINGS = {"SHAPEID_STORE", "SHAPEID_STORE_REFRESH_MS"}
# Allowed values of the settings that take one of a few (server/main.cc's flags).
SETTING_VALUES = {"SHAPEID_LOG_FORMAT": {"text", "json"},
                  "SHAPEID_LOG_LEVEL": {"debug", "info", "warning", "error"}}
ABSL_FLAG = re.compile(r"ABSL_FLAG\(\s*[\w:]+\s*,\s*(\w+)\s*,")
# SHAPEID_STORE for PostgreSQL: a libpq URI, postgres://[user[:password]@]host[:port]/dbname?...
STORE_URI = re.compile(r"^postgres(ql)?://(?:(?P<user>[^:@/]*)(?::(?P<password>[^@/]*))?@)?"
                       r"(?P<host>[^:/?@]+)(?::(?P<port>[0-9]+))?/(?P<db>[^?]+)(\?(?P<query>.*))?$")


def read_server_settings(main_cc):
    """Fills SERVER_SETTINGS from server/main.cc's ABSL_FLAGs, in place (the other modules hold
    the same set). Returns whether the file was there."""
    SERVER_SETTINGS.clear()
    if not main_cc.is_file():
        return False
    SERVER_SETTINGS.update(f"SHAPEID_{flag.upper()}" for flag in ABSL_FLAG.findall(main_cc.read_text()))
    return True


def unknown_settings(keys):
    """The SHAPEID_* names among `keys` that the server has no flag for; none when its flags
    could not be read."""
    if not SERVER_SETTINGS:
        return set()
    return {k for k in keys if k.startswith("SHAPEID_")} - SERVER_SETTINGS


def check_values(c, where, env):
    """Settings that take one of a few values, or a count."""
    for key, allowed in SETTING_VALUES.items():
        if key in env and env[key] not in allowed:
            c.error(where, f"{key}={env[key]!r}: want one of {sorted(allowed)}")
    value = env.get("SHAPEID_METRICS_MAX_GALLERIES")
    if value is not None and not (value.isdigit() and int(value) > 0):
        c.error(where, f"SHAPEID_METRICS_MAX_GALLERIES={value!r}: want a positive count")


def metrics_port(c, where, env, other_ports):
    """SHAPEID_METRICS_LISTEN's port (an int), or None when it is unset or empty. It must be
    reachable from outside the container and differ from the other listening ports."""
    listen = env.get("SHAPEID_METRICS_LISTEN", "")
    if not listen:
        return None
    host, _, port = listen.rpartition(":")
    if not port.isdigit():
        c.error(where, f"SHAPEID_METRICS_LISTEN={listen}: want HOST:PORT")
        return None
    if host in ("127.0.0.1", "localhost", "[::1]"):
        c.error(where, f"SHAPEID_METRICS_LISTEN={listen} is loopback-only: Prometheus cannot "
                       "reach it")
    if int(port) in other_ports:
        c.error(where, f"SHAPEID_METRICS_LISTEN={listen}: its port is the gRPC or health one")
    return int(port)


def listen_ports(env, image):
    """The ports of SHAPEID_LISTEN and SHAPEID_HEALTH_LISTEN."""
    ports = set()
    for key, default in (("SHAPEID_LISTEN", image.get("listen", "")),
                         ("SHAPEID_HEALTH_LISTEN", "")):
        port = env.get(key, default).rpartition(":")[2]
        if port.isdigit():
            ports.add(int(port))
    return ports


def check_store_uri(c, where, uri):
    """A postgres:// SHAPEID_STORE: its parts (a match), and never a password (not printed)."""
    match = STORE_URI.match(uri)
    if match is None:
        c.error(where, "SHAPEID_STORE is not a postgres://[user@]host[:port]/dbname URI")
        return None
    query = (match["query"] or "").split("&")
    if match["password"] is not None or any(p.startswith("password=") for p in query):
        c.error(where, "SHAPEID_STORE holds a password: give it as PGPASSWORD from a Secret")
    return match
