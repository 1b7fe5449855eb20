"""The compose files: compose.yaml (one server on a named volume) and compose.postgres.yaml
(several servers over a PostgreSQL service), and their agreement with the Dockerfile."""

import re

import yaml

from .settings import check_store_uri, check_values, listen_ports, metrics_port, unknown_settings

COMPOSE_TOP = {"name", "services", "volumes", "networks", "configs", "secrets", "version",
               "include"}
# The fields of a Compose service these checks understand; others are reported so that a typo
# is not silently ignored (docker compose rejects unknown service fields).
COMPOSE_SERVICE = {"build", "image", "restart", "ports", "environment", "env_file", "volumes",
                   "read_only", "tmpfs", "cap_drop", "cap_add", "security_opt",
                   "stop_grace_period", "stop_signal", "healthcheck", "command", "entrypoint",
                   "user", "deploy", "logging", "networks", "container_name", "labels",
                   "depends_on", "init", "ulimits", "mem_limit", "cpus", "profiles",
                   "secrets", "expose", "shm_size"}
DURATION = re.compile(r"^([0-9]+(\.[0-9]+)?(us|ms|s|m|h))+$")
# A compose port "[IP:]HOST:CONTAINER[/PROTO]", where IP may be a ${VAR:-default}.
COMPOSE_PORT = re.compile(r"^(?:(?P<ip>\$\{[^}]*\}|[^:]+):)?(?:(?P<host>\$\{[^}]*\}|[0-9-]*):)?"
                          r"(?P<container>[0-9]+)(/\w+)?$")


def is_server(service):
    """A shapeid-server service: built from deploy/Dockerfile or run from a shapeid image."""
    build = service.get("build")
    dockerfile = build.get("dockerfile", "") if isinstance(build, dict) else ""
    return dockerfile.endswith("deploy/Dockerfile") or \
        str(service.get("image", "")).split(":")[0].endswith("shapeid")


def environment(c, swhere, service):
    env = service.get("environment") or {}
    if isinstance(env, list):
        env = dict(e.split("=", 1) if "=" in e else (e, "") for e in env)
    for key, value in env.items():
        if not isinstance(value, str):
            c.error(swhere, f"environment {key}: {value!r}: quote it")
    return {k: str(v) for k, v in env.items()}


def from_outside(value):
    """A value Compose takes from the environment or an --env-file (${VAR...}), not a literal."""
    return bool(re.fullmatch(r"\$\{\w+(:?[-?][^}]*)?\}", value))


def check_database(c, where, name, service, store):
    """The PostgreSQL service that the servers' SHAPEID_STORE names."""
    health = service.get("healthcheck") or {}
    if "pg_isready" not in " ".join(map(str, health.get("test") or [])):
        c.error(where, f"services.{name}: no pg_isready healthcheck, so depends_on cannot wait "
                       "for the database")
    env = environment(c, f"{where} services.{name}", service)
    if not from_outside(env.get("POSTGRES_PASSWORD", "")):
        c.error(where, f"services.{name}: POSTGRES_PASSWORD must be ${{VAR}} from an env file, "
                       "not written here")
    for var, part in (("POSTGRES_USER", "user"), ("POSTGRES_DB", "db")):
        if store[part] and env.get(var, "postgres") != store[part]:
            c.error(where, f"services.{name}: {var}={env.get(var, 'postgres')} but "
                           f"SHAPEID_STORE says {store[part]}")
    targets = [(v.split(":")[1] if isinstance(v, str) and ":" in v else
                (v or {}).get("target") if isinstance(v, dict) else None)
               for v in service.get("volumes") or []]
    if "/var/lib/postgresql/data" not in targets:
        c.error(where, f"services.{name}: /var/lib/postgresql/data is not on a volume: the "
                       "galleries would go with the container")


def check_compose(c, path, image, scaled=False):
    """One server on a named volume, or with scaled several over a PostgreSQL service."""
    where = path.name
    try:
        doc = yaml.safe_load(path.read_text())
    except yaml.YAMLError as e:
        c.error(where, f"YAML: {e}")
        return
    doc = c.fields(where, doc, COMPOSE_TOP | {k for k in (doc or {}) if str(k).startswith("x-")})
    services = doc.get("services") or {}
    if not services:
        c.error(where, "no services")
    named_volumes = set((doc.get("volumes") or {}).keys())
    servers, host_ports, databases = 0, {}, {}
    for name, service in services.items():
        swhere = f"{where} services.{name}"
        service = c.fields(swhere, service, COMPOSE_SERVICE)
        if "image" not in service and "build" not in service:
            c.error(swhere, "needs image or build")
        build = service.get("build")
        if isinstance(build, dict):
            context = (path.parent / build.get("context", ".")).resolve()
            dockerfile = context / build.get("dockerfile", "Dockerfile")
            if not dockerfile.is_file():
                c.error(swhere, f"build: {dockerfile} does not exist")
        env = environment(c, swhere, service)
        targets = {}
        for volume in service.get("volumes") or []:
            if isinstance(volume, str):
                parts = volume.split(":")
                source, target = (parts[0], parts[1]) if len(parts) > 1 else (None, parts[0])
            else:
                source, target = volume.get("source"), volume.get("target")
            if source and not source.startswith((".", "/", "~", "$")) and \
                    source not in named_volumes:
                c.error(swhere, f"volume '{source}' is not declared under top-level volumes")
            targets[target] = source
        if not is_server(service):
            continue
        replicas = (service.get("deploy") or {}).get("replicas", 1)
        servers += replicas if isinstance(replicas, int) else 1
        unknown = unknown_settings(env)
        if unknown:
            c.error(swhere, f"unknown settings {sorted(unknown)}")
        listen_port = env.get("SHAPEID_LISTEN", image.get("listen", "")).rpartition(":")[2]
        check_values(c, swhere, env)
        metrics = metrics_port(c, swhere, env, listen_ports(env, image))
        if metrics is not None and metrics not in image["ports"]:
            c.error(swhere, f"metrics port {metrics} is not EXPOSEd by the Dockerfile")
        published_metrics = False
        if not service.get("ports"):
            c.error(swhere, "no published ports")
        for port in service.get("ports") or []:
            match = COMPOSE_PORT.match(port) if isinstance(port, str) else None
            if match is None:
                c.error(swhere, f"port {port!r}: write it as a quoted \"[IP:]HOST:CONTAINER\"")
                continue
            if metrics is not None and int(match["container"]) == metrics:
                published_metrics = True
                # No authentication on /metrics: loopback unless the operator says otherwise.
                ip = re.fullmatch(r"\$\{(\w+):?-([^}]*)\}", match["ip"] or "")
                default = ip.group(2) if ip else match["ip"]
                if default != "127.0.0.1":
                    c.error(swhere, f"port {port}: the metrics have no authentication: publish "
                                    "them on 127.0.0.1 (by default)")
                elif ip and ip.group(1) == "SHAPEID_HOST_ADDRESS":
                    c.error(swhere, f"port {port}: give the metrics an address variable of "
                                    "their own: opening gRPC (with keys) must not open them")
            elif match["container"] != listen_port or int(match["container"]) not in \
                    image["ports"]:
                c.error(swhere, f"port {port}: the container side must be the listen port "
                                f"{listen_port}, EXPOSEd by the Dockerfile")
            if match["host"]:
                key = (match["ip"], match["host"])
                if key in host_ports:
                    c.error(swhere, f"host port {match['host']} is {host_ports[key]}'s too")
                if replicas != 1:
                    c.error(swhere, f"host port {match['host']} on {replicas} replicas: the "
                                    "second cannot bind it")
                host_ports[key] = name
        if metrics is not None and not published_metrics:
            c.error(swhere, f"SHAPEID_METRICS_LISTEN's port {metrics} is not published")
        data_dir = env.get("SHAPEID_DATA_DIR", image.get("data_dir"))
        if scaled:
            store = check_store_uri(c, swhere, env.get("SHAPEID_STORE", ""))
            if service.get("volumes"):
                c.error(swhere, "volumes on a server over PostgreSQL: it keeps nothing locally")
            if not from_outside(env.get("PGPASSWORD", "")):
                c.error(swhere, "PGPASSWORD must be ${VAR} from an env file, not written here")
            if store is not None:
                depends = service.get("depends_on") or {}
                condition = (depends.get(store["host"]) or {}).get("condition") \
                    if isinstance(depends, dict) else None
                if store["host"] not in services:
                    c.error(swhere, f"SHAPEID_STORE's host {store['host']} is not a service")
                else:
                    databases[store["host"]] = store
                if condition != "service_healthy":
                    c.error(swhere, f"depends_on {store['host']} needs condition "
                                    "service_healthy: the servers would start before the "
                                    "database accepts them")
        else:
            if "SHAPEID_STORE" in env:
                c.error(swhere, "SHAPEID_STORE in the one-server variant (compose.postgres.yaml "
                                "is the shared one)")
            if replicas != 1:
                c.error(swhere, "replicas: one server per volume")
            if data_dir not in targets:
                c.error(swhere, f"the data directory {data_dir} is not on a volume")
        health = c.fields(f"{swhere}.healthcheck", service.get("healthcheck"),
                          {"test", "interval", "timeout", "retries", "start_period",
                           "start_interval", "disable"})
        test = health.get("test")
        if not (isinstance(test, list) and test and test[0] in ("CMD", "CMD-SHELL")
                and "health" in test):
            c.error(swhere, f"healthcheck.test should run ['CMD', 'shapeid', ..., 'health'], "
                            f"got {test!r}")
        for key in ("interval", "timeout", "start_period"):
            if key in health and not DURATION.match(str(health[key])):
                c.error(swhere, f"healthcheck.{key} {health[key]!r} is not a duration")
        if "stop_grace_period" in service and \
                not DURATION.match(str(service["stop_grace_period"])):
            c.error(swhere, "stop_grace_period is not a duration")
        if service.get("read_only") and "/tmp" not in (service.get("tmpfs") or []) and \
                "/tmp" not in targets:
            c.error(swhere, "read_only without a writable /tmp")
    for name, store in databases.items():
        check_database(c, where, name, services[name], store)
    if scaled and servers < 2:
        c.error(where, f"{servers} server(s): the PostgreSQL variant runs at least 2")
    if not scaled and servers != 1:
        c.error(where, f"{servers} servers: one per volume")
