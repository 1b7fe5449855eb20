"""A Kubernetes Deployment and its pod: metadata, probes, the container's fields, resources,
security context, environment (ConfigMaps and Secrets), volumes, the metrics endpoint and its
annotations, the data directory or the PostgreSQL store, and the shutdown timing."""

from .checker import matches, quantity
from .k8s_schema import (CONTAINER, CONTAINER_PORT, DEPLOYMENT_SPEC, DNS_LABEL, ENV_SOURCES,
                         GRPC_ACTION, OBJECT_META, POD_SECURITY_CONTEXT, POD_SPEC, PROBE,
                         PROBE_HANDLERS, RESOURCES, SECURITY_CONTEXT, VOLUME_MOUNT,
                         VOLUME_SOURCES)
from .settings import check_store_uri, check_values, listen_ports, metrics_port, unknown_settings

def check_meta(c, where, doc):
    meta = c.fields(f"{where} metadata", doc.get("metadata"), OBJECT_META)
    name = meta.get("name")
    if not isinstance(name, str) or not DNS_LABEL.match(name) or len(name) > 63:
        c.error(where, f"metadata.name {name!r} is not a DNS-1123 label")
    for key, value in (meta.get("labels") or {}).items():
        if not isinstance(value, str):
            c.error(where, f"label {key} must be a string, got {value!r}")
    return name


def check_probe(c, where, probe, port_numbers, port_names):
    probe = c.fields(where, probe, PROBE)
    handlers = [h for h in PROBE_HANDLERS if h in probe]
    if handlers != ["grpc"]:
        c.error(where, f"want the native grpc probe alone, got {handlers}")
        return
    grpc = c.fields(f"{where}.grpc", probe["grpc"], GRPC_ACTION)
    port = grpc.get("port")
    # The grpc action takes a port number only (no named ports).
    if c.integer(f"{where}.grpc.port", port, 1) and port not in port_numbers:
        c.error(where, f"grpc port {port} is not a containerPort {sorted(port_numbers)}")
    for key in ("initialDelaySeconds", "timeoutSeconds", "periodSeconds", "successThreshold",
                "failureThreshold"):
        if key in probe:
            c.integer(f"{where}.{key}", probe[key], 0)


def check_container(c, where, container, volume_names, configmaps):
    container = c.fields(where, container, CONTAINER)
    c.require(where, container, "name", "image")
    ports = container.get("ports") or []
    if not ports:
        c.error(where, "no ports")
    port_numbers, port_names = set(), set()
    for i, port in enumerate(ports):
        port = c.fields(f"{where}.ports[{i}]", port, CONTAINER_PORT)
        if c.integer(f"{where}.ports[{i}].containerPort", port.get("containerPort"), 1):
            port_numbers.add(port["containerPort"])
        if "name" in port:
            port_names.add(port["name"])
    for probe in ("readinessProbe", "livenessProbe"):
        if probe not in container:
            c.error(where, f"no {probe}")
    for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
        if probe in container:
            check_probe(c, f"{where}.{probe}", container[probe], port_numbers, port_names)

    resources = c.fields(f"{where}.resources", container.get("resources"), RESOURCES)
    for kind in ("requests", "limits"):
        for res in ("cpu", "memory"):
            if quantity((resources.get(kind) or {}).get(res)) is None:
                c.error(where, f"resources.{kind}.{res} missing or not a quantity")
    for res in ("cpu", "memory"):
        low = quantity((resources.get("requests") or {}).get(res))
        high = quantity((resources.get("limits") or {}).get(res))
        if low is not None and high is not None and low > high:
            c.error(where, f"resources.requests.{res} is above the limit")

    sc = c.fields(f"{where}.securityContext", container.get("securityContext"),
                  SECURITY_CONTEXT)
    if sc.get("allowPrivilegeEscalation") is not False:
        c.error(where, "securityContext.allowPrivilegeEscalation must be false")
    if sc.get("readOnlyRootFilesystem") is not True:
        c.error(where, "securityContext.readOnlyRootFilesystem must be true")
    if sc.get("privileged"):
        c.error(where, "securityContext.privileged")
    if "ALL" not in ((sc.get("capabilities") or {}).get("drop") or []):
        c.error(where, "securityContext.capabilities.drop must include ALL")

    env, secret_env = {}, {}  # name -> value; name -> (Secret, key)
    for i, source in enumerate(container.get("envFrom") or []):
        ref = (source or {}).get("configMapRef")
        if ref is not None:
            name = ref.get("name")
            if name not in configmaps:
                c.error(f"{where}.envFrom[{i}]", f"ConfigMap '{name}' is not defined")
            else:
                env.update(configmaps[name])
    for i, var in enumerate(container.get("env") or []):
        if not isinstance(var, dict) or "name" not in var:
            c.error(f"{where}.env[{i}]", "needs a name")
            continue
        source = var.get("valueFrom") or {}
        if ("value" in var) == bool(source) or len(source) > 1 or set(source) - ENV_SOURCES:
            c.error(f"{where}.env[{i}]", f"{var['name']}: want a value or one of "
                                         f"{sorted(ENV_SOURCES)}")
        if "value" in var:
            if not isinstance(var["value"], str):
                c.error(f"{where}.env[{i}]", f"value of {var['name']} must be a string")
            if "PASSWORD" in var["name"].upper():
                c.error(f"{where}.env[{i}]", f"{var['name']} is written in the manifest: take "
                                             "it from a Secret (secretKeyRef)")
            env[var["name"]] = str(var["value"])
        ref = source.get("secretKeyRef")
        if ref is not None:
            secret_env[var["name"]] = (ref.get("name"), ref.get("key"))
        ref = source.get("configMapKeyRef")
        if ref is not None:
            data = configmaps.get(ref.get("name"))
            if data is None or ref.get("key") not in data:
                c.error(f"{where}.env[{i}]", f"configMapKeyRef {ref} does not exist")
            else:
                env[var["name"]] = data[ref["key"]]

    mounts = {}
    for i, mount in enumerate(container.get("volumeMounts") or []):
        mount = c.fields(f"{where}.volumeMounts[{i}]", mount, VOLUME_MOUNT)
        c.require(f"{where}.volumeMounts[{i}]", mount, "name", "mountPath")
        if mount.get("name") not in volume_names:
            c.error(f"{where}.volumeMounts[{i}]", f"volume '{mount.get('name')}' not defined")
        mounts[mount.get("mountPath")] = mount
    return container, port_numbers, port_names, env, secret_env, mounts


def check_pod_metrics(c, where, env, container, annotations, image):
    """The metrics endpoint on a containerPort named `metrics`, which the prometheus.io pod
    annotations name. Returns (port, its name) or (None, None)."""
    for key, value in (annotations or {}).items():
        if not isinstance(value, str):
            c.error(where, f"pod annotation {key}: {value!r} must be a string (quote it)")
    port = metrics_port(c, where, env, listen_ports(env, image))
    if port is None:
        c.error(where, "no SHAPEID_METRICS_LISTEN: these manifests are scraped by Prometheus "
                       "(pod annotations), so the endpoint must be on")
        return None, None
    names = [p.get("name") for p in container.get("ports") or []
             if isinstance(p, dict) and p.get("containerPort") == port]
    if names != ["metrics"]:
        c.error(where, f"SHAPEID_METRICS_LISTEN's port {port} must be one containerPort named "
                       f"`metrics`, got names {names}")
    if image["ports"] and port not in image["ports"]:
        c.error(where, f"metrics port {port} is not EXPOSEd by the Dockerfile")
    want = {"prometheus.io/scrape": "true", "prometheus.io/port": str(port),
            "prometheus.io/path": "/metrics"}
    for key, value in want.items():
        if (annotations or {}).get(key) != value:
            c.error(where, f"pod annotation {key}: {(annotations or {}).get(key)!r}, want "
                           f"{value!r} (SHAPEID_METRICS_LISTEN)")
    return port, "metrics"


def pre_stop_seconds(container):
    """How long a preStop hook of `sleep N` (exec or the native sleep action) pauses, or 0."""
    hook = (container.get("lifecycle") or {}).get("preStop") or {}
    command = (hook.get("exec") or {}).get("command") or []
    if len(command) == 2 and str(command[0]).endswith("sleep") and str(command[1]).isdigit():
        return int(command[1])
    seconds = (hook.get("sleep") or {}).get("seconds")
    return seconds if isinstance(seconds, int) else 0


def check_deployment(c, where, doc, configmaps, claims, image, scaled):
    """scaled: replicas over a shared PostgreSQL store (k8s/scaled/), else one server on a
    PersistentVolumeClaim (k8s/)."""
    spec = c.fields(f"{where} spec", doc.get("spec"), DEPLOYMENT_SPEC)
    replicas = spec.get("replicas", 1)
    strategy = spec.get("strategy") or {}
    if not scaled:
        if replicas != 1:
            c.error(where, "replicas must be 1: one server per data directory")
        if strategy.get("type") != "Recreate":
            c.error(where, "strategy.type must be Recreate: the old server must release the "
                           "volume before the new one starts")
    else:
        if c.integer(f"{where} spec.replicas", replicas) and replicas < 2:
            c.error(where, f"replicas {replicas}: the scaled variant needs at least 2")
        rolling = strategy.get("rollingUpdate") or {}
        if strategy.get("type", "RollingUpdate") != "RollingUpdate":
            c.error(where, "strategy.type must be RollingUpdate")
        if rolling.get("maxUnavailable") not in (0, "0%"):
            c.error(where, "rollingUpdate.maxUnavailable must be 0: a rollout must not take a "
                           "replica away before its successor is ready")
        if rolling.get("maxSurge") in (None, 0, "0%"):
            c.error(where, "rollingUpdate.maxSurge must be at least 1 (with maxUnavailable 0)")
    template = spec.get("template") or {}
    labels = (template.get("metadata") or {}).get("labels") or {}
    selector = (spec.get("selector") or {}).get("matchLabels") or {}
    if not selector:
        c.error(where, "spec.selector.matchLabels is empty")
    for key, value in selector.items():
        if labels.get(key) != value:
            c.error(where, f"selector {key}={value} does not match the pod template's labels")
    pod = c.fields(f"{where} pod spec", template.get("spec"), POD_SPEC)

    volumes = {}
    for i, volume in enumerate(pod.get("volumes") or []):
        name = (volume or {}).get("name")
        sources = [k for k in volume if k != "name"] if isinstance(volume, dict) else []
        if len(sources) != 1 or sources[0] not in VOLUME_SOURCES:
            c.error(f"{where} volumes[{i}]", f"want one known volume source, got {sources}")
        if name in volumes:
            c.error(f"{where} volumes[{i}]", f"duplicate volume '{name}'")
        volumes[name] = volume
        claim = (volume.get("persistentVolumeClaim") or {}).get("claimName")
        if scaled and ("persistentVolumeClaim" in volume or "ephemeral" in volume):
            c.error(f"{where} volumes[{i}]", "a claim in the scaled variant: its pods keep "
                                             "nothing, the galleries are in PostgreSQL")
        elif "persistentVolumeClaim" in volume and claim not in claims:
            c.error(f"{where} volumes[{i}]", f"PersistentVolumeClaim '{claim}' not defined")
        config = (volume.get("configMap") or {}).get("name")
        if "configMap" in volume and config not in configmaps:
            c.error(f"{where} volumes[{i}]", f"ConfigMap '{config}' not defined")

    psc = c.fields(f"{where} pod securityContext", pod.get("securityContext"),
                   POD_SECURITY_CONTEXT)
    if psc.get("runAsNonRoot") is not True:
        c.error(where, "pod securityContext.runAsNonRoot must be true")
    for key in ("runAsUser", "fsGroup"):
        if not isinstance(psc.get(key), int) or psc.get(key) == 0:
            c.error(where, f"pod securityContext.{key} must be a non-zero uid/gid")
    if image.get("uid") is not None and psc.get("runAsUser") != image["uid"]:
        c.error(where, f"runAsUser {psc.get('runAsUser')} is not the image's USER "
                       f"{image['uid']}")

    if scaled:
        terms = (((pod.get("affinity") or {}).get("podAntiAffinity") or {})
                 .get("preferredDuringSchedulingIgnoredDuringExecution") or [])
        if not any(isinstance(term, dict) and isinstance(term.get("podAffinityTerm"), dict)
                   and term["podAffinityTerm"].get("topologyKey") == "kubernetes.io/hostname"
                   and matches(((term["podAffinityTerm"].get("labelSelector") or {})
                                .get("matchLabels")), labels)
                   for term in terms):
            c.error(where, "no preferred podAntiAffinity on kubernetes.io/hostname selecting "
                           "its own pods: the replicas could all land on one node")

    containers = pod.get("containers") or []
    if len(containers) != 1:
        c.error(where, f"want one container, got {len(containers)}")
    result = {"where": where, "labels": labels, "ports": set(), "port_names": set(),
              "replicas": replicas, "secret_refs": set(), "store": None,
              "metrics": (None, None)}
    for i, container in enumerate(containers):
        cwhere = f"{where} containers[{i}]"
        container, numbers, names, env, secret_env, mounts = check_container(
            c, cwhere, container, set(volumes), configmaps)
        result["ports"] |= numbers
        result["port_names"] |= names
        result["secret_refs"] |= set(secret_env.values())
        unknown = unknown_settings({**env, **secret_env})
        if unknown:
            c.error(cwhere, f"unknown settings {sorted(unknown)}")
        check_values(c, cwhere, env)
        result["metrics"] = check_pod_metrics(
            c, cwhere, env, container, (template.get("metadata") or {}).get("annotations"),
            image)
        data_dir = env.get("SHAPEID_DATA_DIR", image.get("data_dir"))
        mount = mounts.get(data_dir)
        if scaled:
            store = env.get("SHAPEID_STORE", "")
            if "SHAPEID_STORE" in secret_env:
                pass  # the whole URI from a Secret: nothing to read here
            elif not store.startswith(("postgres://", "postgresql://")):
                c.error(cwhere, f"SHAPEID_STORE {store!r}: replicas share galleries only "
                                "through a postgres:// store")
            else:
                result["store"] = check_store_uri(c, cwhere, store)
                if "PGPASSWORD" not in secret_env:
                    c.error(cwhere, "PGPASSWORD must come from a Secret (valueFrom.secretKeyRef)")
        elif mount is None:
            c.error(cwhere, f"the data directory {data_dir} is not a volume mount: galleries "
                            "would be lost with the pod")
        elif "persistentVolumeClaim" not in volumes.get(mount["name"], {}):
            c.error(cwhere, f"the data directory {data_dir} is not on a PersistentVolumeClaim")
        elif mount.get("readOnly"):
            c.error(cwhere, f"the data directory {data_dir} is mounted read-only")
        listen = env.get("SHAPEID_LISTEN", image.get("listen", ""))
        host, _, port = listen.rpartition(":")
        if host in ("127.0.0.1", "localhost", "[::1]"):
            c.error(cwhere, f"SHAPEID_LISTEN={listen} is loopback-only: probes and the "
                            "Service cannot reach it")
        if not port.isdigit() or int(port) not in numbers:
            c.error(cwhere, f"SHAPEID_LISTEN={listen} is not on a containerPort")
        if "/tmp" not in mounts:
            c.error(cwhere, "read-only root file system without a writable /tmp mount")
        grace = pod.get("terminationGracePeriodSeconds", 30)
        drain = env.get("SHAPEID_SHUTDOWN_GRACE_SECONDS", "10")
        pause = pre_stop_seconds(container)
        if drain.isdigit() and int(drain) + pause >= grace:
            c.error(cwhere, f"SHAPEID_SHUTDOWN_GRACE_SECONDS={drain} plus the preStop pause "
                            f"({pause} s) must be below terminationGracePeriodSeconds={grace}")
    return result
