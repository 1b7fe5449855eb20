#!/usr/bin/python3
"""Offline check of deploy/'s compose files and Kubernetes manifests, and of their agreement
with the Dockerfile.

Two variants of each: one server on its own volume (compose.yaml, k8s/) and several replicas
sharing PostgreSQL (compose.postgres.yaml, k8s/scaled/ and its dev-only dev-postgres/).

No cluster or schema download is available offline (CI reaches Debian's mirror only), and
`kubectl apply --dry-run=client` cannot run without one: even client-side dry runs ask an API
server for discovery (this machine image has Google Cloud SDK's kubectl, which fails there with
"connection refused"; `kubectl kustomize` does work offline and test_container.sh runs it when
kubectl is present). So this does by hand what a client-side dry run would catch here:
YAML that parses, apiVersion/kind/metadata.name, field names (against the subset of the API
schema these kinds use: a typo such as `readinesProbe` is an error, as kubectl's strict field
validation makes it), value types, and every cross-reference: selectors and labels, volume mounts
and volumes, ConfigMap and PersistentVolumeClaim names, probe and Service ports, the data
directory, the image's user, port and volume. For the replicas: at least two, a rollout that
never lowers capacity, no claim, a disruption budget, anti-affinity, a headless Service whose
port is the pods' own, the database password from a Secret (never a literal), and the copies of
k8s/ files kept identical.

Metrics (issue 12): the metrics endpoint on a containerPort `metrics` that the pod annotations
prometheus.io/scrape, /port and /path and every Service's `metrics` port name; in compose, its
port EXPOSEd and published on loopback by default. The Grafana dashboard (grafana/): valid JSON,
its variables, every panel titled with queries, units, and every metric and label its PromQL
names among those the server exports (METRICS below); its kustomization for Grafana's sidecar.

    /usr/bin/python3 deploy/check_manifests.py [DEPLOY_DIR]

Needs python3-yaml (Debian). Prints one line per problem and exits 1 if there is any.
"""

import json
import pathlib
import re
import sys

import yaml

DNS_LABEL = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")

# Field names per object, from the Kubernetes API reference (v1.29). Only the objects these
# manifests use are checked field by field; the rest are checked by the cross-reference rules.
OBJECT_META = {"name", "namespace", "labels", "annotations", "generateName", "finalizers",
               "ownerReferences"}
DEPLOYMENT_SPEC = {"replicas", "selector", "template", "strategy", "minReadySeconds",
                   "revisionHistoryLimit", "paused", "progressDeadlineSeconds"}
POD_SPEC = {"volumes", "initContainers", "containers", "ephemeralContainers", "restartPolicy",
            "terminationGracePeriodSeconds", "activeDeadlineSeconds", "dnsPolicy",
            "nodeSelector", "serviceAccountName", "serviceAccount",
            "automountServiceAccountToken", "nodeName", "hostNetwork", "hostPID", "hostIPC",
            "shareProcessNamespace", "securityContext", "imagePullSecrets", "hostname",
            "subdomain", "affinity", "schedulerName", "tolerations", "hostAliases",
            "priorityClassName", "priority", "dnsConfig", "readinessGates", "runtimeClassName",
            "enableServiceLinks", "preemptionPolicy", "overhead", "topologySpreadConstraints",
            "setHostnameAsFQDN", "os", "hostUsers", "schedulingGates", "resourceClaims"}
CONTAINER = {"name", "image", "command", "args", "workingDir", "ports", "envFrom", "env",
             "resources", "resizePolicy", "restartPolicy", "volumeMounts", "volumeDevices",
             "livenessProbe", "readinessProbe", "startupProbe", "lifecycle",
             "terminationMessagePath", "terminationMessagePolicy", "imagePullPolicy",
             "securityContext", "stdin", "stdinOnce", "tty"}
CONTAINER_PORT = {"name", "hostPort", "containerPort", "protocol", "hostIP"}
PROBE = {"exec", "httpGet", "tcpSocket", "grpc", "initialDelaySeconds", "timeoutSeconds",
         "periodSeconds", "successThreshold", "failureThreshold",
         "terminationGracePeriodSeconds"}
PROBE_HANDLERS = {"exec", "httpGet", "tcpSocket", "grpc"}
GRPC_ACTION = {"port", "service"}
SECURITY_CONTEXT = {"capabilities", "privileged", "seLinuxOptions", "windowsOptions",
                    "runAsUser", "runAsGroup", "runAsNonRoot", "readOnlyRootFilesystem",
                    "allowPrivilegeEscalation", "procMount", "seccompProfile",
                    "appArmorProfile"}
POD_SECURITY_CONTEXT = {"seLinuxOptions", "windowsOptions", "runAsUser", "runAsGroup",
                        "runAsNonRoot", "supplementalGroups", "supplementalGroupsPolicy",
                        "fsGroup", "sysctls", "fsGroupChangePolicy", "seccompProfile",
                        "appArmorProfile", "seLinuxChangePolicy"}
RESOURCES = {"requests", "limits", "claims"}
VOLUME_MOUNT = {"name", "readOnly", "recursiveReadOnly", "mountPath", "subPath",
                "mountPropagation", "subPathExpr"}
VOLUME_SOURCES = {"emptyDir", "persistentVolumeClaim", "configMap", "secret", "hostPath",
                  "projected", "downwardAPI", "ephemeral", "csi", "nfs", "iscsi", "image",
                  "awsElasticBlockStore", "gcePersistentDisk", "azureDisk", "azureFile",
                  "cephfs", "cinder", "fc", "flexVolume", "flocker", "gitRepo", "glusterfs",
                  "photonPersistentDisk", "portworxVolume", "quobyte", "rbd", "scaleIO",
                  "storageos", "vsphereVolume"}
SERVICE_SPEC = {"ports", "selector", "clusterIP", "clusterIPs", "type", "externalIPs",
                "sessionAffinity", "loadBalancerIP", "loadBalancerSourceRanges", "externalName",
                "externalTrafficPolicy", "healthCheckNodePort", "publishNotReadyAddresses",
                "sessionAffinityConfig", "ipFamilies", "ipFamilyPolicy",
                "allocateLoadBalancerNodePorts", "loadBalancerClass", "internalTrafficPolicy",
                "trafficDistribution"}
SERVICE_PORT = {"name", "protocol", "appProtocol", "port", "targetPort", "nodePort"}
PVC_SPEC = {"accessModes", "selector", "resources", "volumeName", "storageClassName",
            "volumeMode", "dataSource", "dataSourceRef", "volumeAttributesClassName"}
ACCESS_MODES = {"ReadWriteOnce", "ReadOnlyMany", "ReadWriteMany", "ReadWriteOncePod"}
KUSTOMIZATION = {"apiVersion", "kind", "resources", "images", "labels", "commonLabels",
                 "commonAnnotations", "namespace", "namePrefix", "nameSuffix", "patches",
                 "configMapGenerator", "secretGenerator", "generatorOptions", "replicas",
                 "components"}
PDB_SPEC = {"minAvailable", "maxUnavailable", "selector", "unhealthyPodEvictionPolicy"}
ENV_SOURCES = {"configMapKeyRef", "secretKeyRef", "fieldRef", "resourceFieldRef"}
KINDS = {"ConfigMap": "v1", "Service": "v1", "PersistentVolumeClaim": "v1",
         "Secret": "v1", "Deployment": "apps/v1", "PodDisruptionBudget": "policy/v1"}
SECRET = {"apiVersion", "kind", "metadata", "type", "data", "stringData", "immutable"}
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
# The server's settings: SHAPEID_<FLAG> for every ABSL_FLAG in server/main.cc (read there, so a
# new flag needs no change here); this list only when the deploy folder is checked on its own.
SERVER_SETTINGS = {"SHAPEID_LISTEN", "SHAPEID_DATA_DIR", "SHAPEID_MAX_POINTS_PER_CLOUD",
                   "SHAPEID_MAX_MESSAGE_BYTES", "SHAPEID_SET_ASIDE_DAMAGED",
                   "SHAPEID_SHUTDOWN_GRACE_SECONDS"}
# The settings that only the PostgreSQL variants have.
STORE_SETTINGS = {"SHAPEID_STORE", "SHAPEID_STORE_REFRESH_MS"}
# Allowed values of the settings that take one of a few (server/main.cc's flags).
SETTING_VALUES = {"SHAPEID_LOG_FORMAT": {"text", "json"},
                  "SHAPEID_LOG_LEVEL": {"debug", "info", "warning", "error"}}
# The metrics shapeid-server exports (server/metrics.cc, docs/operations.md): name -> (type,
# labels). The dashboard may name these and no others. This is the one list here; the same
# dashboard is also checked against a real server's scrape by tests/operations_e2e_test.cc, so
# a metric renamed in the server fails there, and this list must follow it.
METRICS = {
    "shapeid_requests_total": ("counter", {"method", "gallery", "code"}),
    "shapeid_points_received_total": ("counter", {"method"}),
    "shapeid_samples_trained_total": ("counter", {"gallery"}),
    "shapeid_store_write_failures_total": ("counter", {"operation"}),
    "shapeid_replication_changes_applied_total": ("counter", set()),
    "shapeid_request_duration_seconds": ("histogram", {"method"}),
    "shapeid_describe_duration_seconds": ("histogram", {"descriptor"}),
    "shapeid_search_duration_seconds": ("histogram", {"index"}),
    "shapeid_store_write_duration_seconds": ("histogram", {"operation"}),
    "shapeid_request_wait_seconds": ("histogram", {"method"}),
    "shapeid_work_wait_seconds": ("histogram", {"lane"}),
    "shapeid_requests_in_flight": ("gauge", set()),
    "shapeid_workers": ("gauge", {"lane"}),
    "shapeid_work_running": ("gauge", {"lane"}),
    "shapeid_work_queued": ("gauge", {"lane"}),
    "shapeid_memory_budget_bytes": ("gauge", set()),
    "shapeid_memory_held_bytes": ("gauge", set()),
    "shapeid_memory_held_peak_bytes": ("gauge", set()),
    "shapeid_serving": ("gauge", set()),
    "shapeid_galleries": ("gauge", set()),
    "shapeid_gallery_samples": ("gauge", {"gallery"}),
    "shapeid_gallery_labels_folded": ("gauge", set()),
    "shapeid_store_reachable": ("gauge", set()),
    "shapeid_replication_sync_age_seconds": ("gauge", set()),
    "shapeid_build_info": ("gauge", {"version"}),
    "process_resident_memory_bytes": ("gauge", set()),
    "process_virtual_memory_bytes": ("gauge", set()),
    "process_cpu_seconds_total": ("counter", set()),
    "process_open_fds": ("gauge", set()),
    "process_max_fds": ("gauge", set()),
    "process_start_time_seconds": ("gauge", set()),
    "process_threads": ("gauge", set()),
}
# Labels that Prometheus' scrape configuration adds to every series (job and instance always;
# the others by the usual Kubernetes relabelling).
TARGET_LABELS = {"job", "instance", "pod", "namespace", "node", "container", "service",
                 "endpoint"}
HISTOGRAM_SUFFIXES = ("_bucket", "_sum", "_count")
METRIC_NAME = re.compile(r"\b(?:shapeid|process)_[a-z_]+")
# Label names in PromQL: in by/without/on/ignoring lists and before a matcher operator.
LABEL_LIST = re.compile(r"\b(?:by|without|on|ignoring)\s*\(([^)]*)\)")
SELECTOR = re.compile(r"\{([^{}]*)\}")
MATCHER = re.compile(r"(\w+)\s*(?:=~|!~|!=|=)")
LABEL_VALUES = re.compile(r"label_values\(\s*(?:(\w+)\s*(\{[^}]*\})?\s*,\s*)?(\w+)\s*\)")
# Panels that show numbers, so must say their unit.
UNIT_PANELS = {"timeseries", "stat", "bargauge", "gauge"}
# kubectl apply keeps the whole object in an annotation, limited to 256 KiB.
LAST_APPLIED_LIMIT = 262144
DASHBOARD_LABEL = ("grafana_dashboard", "1")
ABSL_FLAG = re.compile(r"ABSL_FLAG\(\s*[\w:]+\s*,\s*(\w+)\s*,")
QUANTITY = re.compile(r"^([0-9.]+)(m|k|M|G|T|P|E|Ki|Mi|Gi|Ti|Pi|Ei)?$")
SCALE = {None: 1, "m": 1e-3, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12, "P": 1e15, "E": 1e18,
         "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "Pi": 2**50, "Ei": 2**60}
DURATION = re.compile(r"^([0-9]+(\.[0-9]+)?(us|ms|s|m|h))+$")
# SHAPEID_STORE for PostgreSQL: a libpq URI, postgres://[user[:password]@]host[:port]/dbname?...
STORE_URI = re.compile(r"^postgres(ql)?://(?:(?P<user>[^:@/]*)(?::(?P<password>[^@/]*))?@)?"
                       r"(?P<host>[^:/?@]+)(?::(?P<port>[0-9]+))?/(?P<db>[^?]+)(\?(?P<query>.*))?$")
# A compose port "[IP:]HOST:CONTAINER[/PROTO]", where IP may be a ${VAR:-default}.
COMPOSE_PORT = re.compile(r"^(?:(?P<ip>\$\{[^}]*\}|[^:]+):)?(?:(?P<host>\$\{[^}]*\}|[0-9-]*):)?"
                          r"(?P<container>[0-9]+)(/\w+)?$")


class Checker:
    def __init__(self):
        self.problems = []

    def error(self, where, message):
        self.problems.append(f"{where}: {message}")

    def fields(self, where, obj, allowed):
        """obj must be a mapping whose keys are all in `allowed`; returns it (or {})."""
        if not isinstance(obj, dict):
            self.error(where, f"expected a mapping, got {type(obj).__name__}")
            return {}
        for key in obj:
            if key not in allowed:
                self.error(where, f"unknown field '{key}'")
        return obj

    def require(self, where, obj, *keys):
        for key in keys:
            if key not in obj:
                self.error(where, f"missing '{key}'")

    def integer(self, where, value, low=None):
        if not isinstance(value, int) or isinstance(value, bool):
            self.error(where, f"expected an integer, got {value!r}")
            return False
        if low is not None and value < low:
            self.error(where, f"{value} is below {low}")
            return False
        return True


def quantity(text):
    match = QUANTITY.match(str(text))
    return None if match is None else float(match.group(1)) * SCALE[match.group(2)]


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
        unknown = {k for k in {**env, **secret_env} if k.startswith("SHAPEID_")} - \
            SERVER_SETTINGS
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


def matches(selector, labels):
    """A non-empty matchLabels selector that the labels satisfy."""
    return bool(selector) and isinstance(selector, dict) and \
        all(labels.get(k) == v for k, v in selector.items())


def check_service(c, where, doc, deployments):
    """Returns whether the Service is headless."""
    spec = c.fields(f"{where} spec", doc.get("spec"), SERVICE_SPEC)
    selector = spec.get("selector") or {}
    targets = [d for d in deployments if matches(selector, d["labels"])]
    if not targets:
        c.error(where, f"selector {selector} matches no Deployment's pods")
    headless = spec.get("clusterIP") == "None"
    if headless and spec.get("type", "ClusterIP") != "ClusterIP":
        c.error(where, "clusterIP None needs type ClusterIP")
    if headless and spec.get("publishNotReadyAddresses"):
        c.error(where, "publishNotReadyAddresses would give clients pods that are loading or "
                       "cut off from the database")
    ports = spec.get("ports") or []
    if not ports:
        c.error(where, "no ports")
    for i, port in enumerate(ports):
        port = c.fields(f"{where} ports[{i}]", port, SERVICE_PORT)
        c.integer(f"{where} ports[{i}].port", port.get("port"), 1)
        target = port.get("targetPort", port.get("port"))
        for d in targets:
            if target not in d["ports"] and target not in d["port_names"]:
                c.error(f"{where} ports[{i}]", f"targetPort {target!r} is not a containerPort")
            # No translation without a cluster IP: clients dial POD-IP:port.
            if headless and port.get("port") not in d["ports"]:
                c.error(f"{where} ports[{i}]", f"port {port.get('port')!r} of a headless "
                                               f"Service must be a containerPort "
                                               f"{sorted(d['ports'])}: clients dial the pods")
    # The metrics, by port name `metrics`, as ServiceMonitors select them.
    for d in targets:
        number, name = d["metrics"]
        if number is None:
            continue
        named = [p for p in ports if isinstance(p, dict) and p.get("name") == "metrics"]
        if len(named) != 1:
            c.error(where, "want one port named `metrics` for the pods' metrics endpoint")
        elif named[0].get("targetPort", named[0].get("port")) not in (number, name):
            c.error(where, f"port `metrics` targets {named[0].get('targetPort')!r}, not the "
                           f"pods' metrics port {name} ({number})")
    return headless


def check_pdb(c, where, doc, deployments):
    spec = c.fields(f"{where} spec", doc.get("spec"), PDB_SPEC)
    if ("minAvailable" in spec) == ("maxUnavailable" in spec):
        c.error(where, "want one of minAvailable and maxUnavailable")
    targets = [d for d in deployments
               if matches((spec.get("selector") or {}).get("matchLabels"), d["labels"])]
    if not targets:
        c.error(where, "selector matches no Deployment's pods")
    low = spec.get("minAvailable")
    for d in targets:
        if isinstance(low, int) and isinstance(d["replicas"], int) and \
                not 1 <= low < d["replicas"]:
            c.error(where, f"minAvailable {low} with {d['replicas']} replicas: want 1 to "
                           f"{d['replicas'] - 1}, or no node holding one could be drained")


def load_docs(c, directory, label):
    """(file, document) for every YAML document of directory/*.yaml; label names the files."""
    docs = []
    for path in sorted(directory.glob("*.yaml")):
        try:
            for doc in yaml.safe_load_all(path.read_text()):
                if doc is not None:
                    docs.append((f"{label}{path.name}", doc))
        except yaml.YAMLError as e:
            c.error(f"{label}{path.name}", f"YAML: {e}")
    return docs


def check_kustomization(c, directory, file, doc, label):
    c.fields(file, doc, KUSTOMIZATION)
    listed = doc.get("resources") or []
    for resource in listed:
        if not (directory / resource).is_file():
            c.error(file, f"resource {resource} does not exist (or is not a file)")
    for path in sorted(directory.glob("*.yaml")):
        if f"{label}{path.name}" != file and path.name not in listed:
            c.error(file, f"{path.name} is not in resources")
    return listed


def documented_secrets(readme):
    """{Secret: keys} that deploy/README.md creates with `kubectl create secret generic`."""
    found = {}
    for command in re.findall(r"kubectl create secret generic [^\n]*",
                              readme.replace("\\\n", " ")):
        words = command.split()
        keys = {re.sub(r"^--from-(literal|file)=", "", w).split("=")[0]
                for w in words if w.startswith(("--from-literal=", "--from-file="))}
        found.setdefault(words[4], set()).update(keys)
    return found


def check_k8s(c, k8s_dir, image, scaled=False, readme=""):
    """One server on a claim (k8s/), or with scaled the replicas over PostgreSQL
    (k8s/scaled/). Returns the number of documents, the Deployments' store URIs (matches) and
    the Secret keys they read."""
    label = "scaled/" if scaled else ""
    docs = load_docs(c, k8s_dir, label)
    objects = {}
    for file, doc in docs:
        if not isinstance(doc, dict):
            c.error(file, "a document is not a mapping")
            continue
        kind = doc.get("kind")
        if kind == "Kustomization":
            listed = check_kustomization(c, k8s_dir, file, doc, label)
            if scaled and any("postgres" in str(r) for r in listed):
                c.error(file, "deploys a PostgreSQL: production uses an operator-managed or "
                              "external one (dev-postgres/ is for trying it out only)")
            continue
        where = f"{file} {kind}"
        c.require(file, doc, "apiVersion", "kind", "metadata")
        if kind not in KINDS or (kind == "PodDisruptionBudget" and not scaled):
            hint = ": the database belongs outside (operator-managed or external)" \
                if kind == "StatefulSet" else ""
            c.error(file, f"unexpected kind {kind!r}{hint}")
            continue
        if doc.get("apiVersion") != KINDS[kind]:
            c.error(where, f"apiVersion {doc.get('apiVersion')!r}, want {KINDS[kind]!r}")
        name = check_meta(c, where, doc)
        if (kind, name) in objects:
            c.error(where, f"{kind} '{name}' defined twice")
        objects[(kind, name)] = (file, doc)

    configmaps = {}
    for (kind, name), (file, doc) in objects.items():
        if kind == "ConfigMap":
            data = doc.get("data") or {}
            for key, value in data.items():
                if not isinstance(value, str):
                    c.error(f"{file} ConfigMap", f"{key}: {value!r} must be a string (quote it)")
                if "PASSWORD" in key.upper():
                    c.error(f"{file} ConfigMap", f"{key}: a password belongs in a Secret")
            unknown = {k for k in data if k.startswith("SHAPEID_")} - SERVER_SETTINGS
            if unknown:
                c.error(f"{file} ConfigMap", f"unknown settings {sorted(unknown)}")
            check_values(c, f"{file} ConfigMap", {k: str(v) for k, v in data.items()})
            if str(data.get("SHAPEID_STORE", "")).startswith("postgres"):
                check_store_uri(c, f"{file} ConfigMap", data["SHAPEID_STORE"])
            configmaps[name] = {k: str(v) for k, v in data.items()}
    claims = set()
    for (kind, name), (file, doc) in objects.items():
        if kind == "PersistentVolumeClaim":
            if scaled:
                c.error(file, "a PersistentVolumeClaim in the scaled variant: its pods keep "
                              "nothing, the galleries are in PostgreSQL")
            spec = c.fields(f"{file} spec", doc.get("spec"), PVC_SPEC)
            modes = spec.get("accessModes") or []
            if not modes or any(m not in ACCESS_MODES for m in modes):
                c.error(file, f"accessModes {modes}")
            if "ReadWriteMany" in modes:
                c.error(file, "ReadWriteMany invites a second server on the same store")
            if quantity(((spec.get("resources") or {}).get("requests") or {}).get("storage")) \
                    is None:
                c.error(file, "resources.requests.storage missing or not a quantity")
            claims.add(name)
    secrets = {}  # name -> keys
    for (kind, name), (file, doc) in objects.items():
        if kind == "Secret":
            c.fields(f"{file} Secret", doc, SECRET)
            for key, value in (doc.get("stringData") or {}).items():
                if not isinstance(value, str):
                    c.error(f"{file} Secret", f"stringData.{key} must be a string")
            secrets[name] = set(doc.get("stringData") or {}) | set(doc.get("data") or {})
    # The server's own rule (docs/security.md): a listen address other than loopback needs
    # API keys or TLS, or an explicit SHAPEID_INSECURE; otherwise the pod would crash-loop.
    for name, data in configmaps.items():
        listen = data.get("SHAPEID_LISTEN", "")
        if listen and not listen.startswith(("127.", "localhost:", "[::1]")) and not (
                data.get("SHAPEID_API_KEYS_FILE") or data.get("SHAPEID_TLS_CERT")
                or data.get("SHAPEID_INSECURE", "false").lower() == "true"):
            c.error(f"ConfigMap {name}", f"SHAPEID_LISTEN {listen} without SHAPEID_API_KEYS_FILE "
                    "or SHAPEID_TLS_CERT: the server refuses to start")
    for (kind, _), (file, doc) in objects.items():
        if kind != "Deployment":
            continue
        volumes = ((((doc.get("spec") or {}).get("template") or {}).get("spec") or {})
                   .get("volumes") or [])
        for volume in volumes:
            secret = (volume.get("secret") or {}).get("secretName") if isinstance(volume, dict) \
                else None
            if secret is not None and secret not in secrets:
                c.error(f"{file} Deployment", f"Secret '{secret}' is not defined")
    deployments = [check_deployment(c, f"{file} Deployment", doc, configmaps, claims, image,
                                    scaled)
                   for (kind, _), (file, doc) in objects.items() if kind == "Deployment"]
    if not deployments:
        c.error(str(k8s_dir), "no Deployment")
    # A Secret that holds a password is not kept in the repository: it must be defined here or
    # created by a command that the README gives, with the keys the pods read.
    created = documented_secrets(readme)
    secret_refs = set()
    for d in deployments:
        secret_refs |= d["secret_refs"]
        for secret, key in sorted(d["secret_refs"], key=str):
            if key not in secrets.get(secret, created.get(secret, set())):
                c.error(d["where"], f"reads key {key!r} of Secret {secret!r}, which is neither "
                                    "defined here nor created with that key by a `kubectl "
                                    "create secret generic` in deploy/README.md")
    headless = [check_service(c, f"{file} Service", doc, deployments)
                for (kind, _), (file, doc) in objects.items() if kind == "Service"]
    if scaled and (True not in headless or False not in headless):
        c.error(str(k8s_dir), "want a headless Service (clusterIP: None) for client-side "
                              "balancing and a ClusterIP one for simple clients")
    for (kind, _), (file, doc) in objects.items():
        if kind == "PodDisruptionBudget":
            check_pdb(c, f"{file} PodDisruptionBudget", doc, deployments)
    needed = ("ConfigMap", "Service") + (("PodDisruptionBudget",) if scaled
                                         else ("PersistentVolumeClaim",))
    for kind in needed:
        if not any(k == kind for k, _ in objects):
            c.error(str(k8s_dir), f"no {kind}")
    stores = [d["store"] for d in deployments if d["store"] is not None]
    return len(docs), stores, secret_refs


def check_promql(c, where, expr):
    """Every metric an expression names is one the server exports (histograms through their
    _bucket/_sum/_count series), and every label it names is one of theirs or a target's."""
    text = re.sub(r'"(?:[^"\\]|\\.)*"', '""', expr)  # label values and regexes are not names
    names, labels = set(), set(TARGET_LABELS)
    found_names = METRIC_NAME.findall(text)
    for found in found_names:
        base, suffix = found, ""
        for s in HISTOGRAM_SUFFIXES:
            if found.endswith(s) and found[:-len(s)] in METRICS:
                base, suffix = found[:-len(s)], s
        if base not in METRICS:
            c.error(where, f"{found}: not a metric the server exports (METRICS)")
            continue
        kind, own = METRICS[base]
        if kind == "histogram" and not suffix:
            c.error(where, f"{found} is a histogram: query its _bucket, _sum or _count series")
        names.add(base)
        labels |= own | ({"le"} if kind == "histogram" else set())
    if not found_names:
        c.error(where, f"names no shapeid or process metric: {expr!r}")
    used = {w.strip() for group in LABEL_LIST.findall(text) for w in group.split(",")
            if w.strip()}
    used |= {m for group in SELECTOR.findall(text) for m in MATCHER.findall(group)}
    for label in sorted(used - labels - {"__name__"}):
        c.error(where, f"label '{label}' belongs to none of {sorted(names)}")
    if "histogram_quantile" in text and not (
            "_bucket" in text and any("le" in [w.strip() for w in g.split(",")]
                                      for g in LABEL_LIST.findall(text))):
        c.error(where, "histogram_quantile needs rate(..._bucket[...]) summed by (..., le)")


def dashboard_panels(panels):
    """Every panel, those inside rows (collapsed rows keep theirs in `panels`) included."""
    for panel in panels or []:
        yield panel
        if isinstance(panel, dict) and panel.get("type") == "row":
            yield from dashboard_panels(panel.get("panels"))


def check_dashboard(c, path):
    """The Grafana dashboard: JSON, variables, and panels whose queries name only what the
    server exports. Returns the number of panels (rows left out)."""
    where = f"grafana/{path.name}"
    try:
        text = path.read_text()
        board = json.loads(text)
    except (OSError, ValueError) as e:
        c.error(where, f"not valid JSON: {e}")
        return 0
    if not isinstance(board, dict):
        c.error(where, "not a JSON object")
        return 0
    if len(text.encode()) >= LAST_APPLIED_LIMIT:
        c.error(where, f"{len(text.encode())} bytes: `kubectl apply` of its ConfigMap keeps "
                       f"a copy in an annotation, limited to {LAST_APPLIED_LIMIT}")
    for key in ("title", "uid"):
        if not isinstance(board.get(key), str) or not board.get(key):
            c.error(where, f"no {key}")
    if not isinstance(board.get("schemaVersion"), int) or board["schemaVersion"] < 36:
        c.error(where, f"schemaVersion {board.get('schemaVersion')!r}: want 36 or later "
                       "(Grafana 9+)")
    refresh = board.get("refresh")
    if not (isinstance(refresh, str) and re.fullmatch(r"[0-9]+[smh]", refresh)) or \
            refresh.endswith("s") and int(refresh[:-1]) < 10:
        c.error(where, f"refresh {refresh!r}: want 10s or longer")
    variables = {v.get("name"): v for v in (board.get("templating") or {}).get("list") or []
                 if isinstance(v, dict)}
    source = variables.get("datasource") or {}
    if source.get("type") != "datasource" or source.get("query") != "prometheus":
        c.error(where, "no `datasource` variable of type datasource for prometheus")
    if not any(variables.get(n, {}).get("type") == "query" for n in ("instance", "pod")):
        c.error(where, "no `instance` (or `pod`) query variable")
    for name, variable in variables.items():
        if variable.get("type") != "query":
            continue
        query = variable.get("query")
        query = query.get("query") if isinstance(query, dict) else query
        match = LABEL_VALUES.fullmatch(str(query).strip())
        if match is None:
            c.error(f"{where} variable {name}", f"want label_values(METRIC{{...}}, LABEL), "
                                                f"got {query!r}")
            continue
        metric, selector, label = match.groups()
        if metric is None:
            c.error(f"{where} variable {name}", "label_values without a metric reads every "
                                                "job's series")
            continue
        check_promql(c, f"{where} variable {name}", metric + (selector or ""))
        if label not in METRICS.get(metric, ("", set()))[1] | TARGET_LABELS:
            c.error(f"{where} variable {name}", f"{metric} has no label '{label}'")
    ids, count = set(), 0
    for panel in dashboard_panels(board.get("panels")):
        if not isinstance(panel, dict):
            c.error(where, "a panel is not an object")
            continue
        pwhere = f"{where} panel {panel.get('id')} {panel.get('title')!r}"
        if panel.get("id") in ids:
            c.error(pwhere, "duplicate id")
        ids.add(panel.get("id"))
        grid = panel.get("gridPos") or {}
        if not all(isinstance(grid.get(k), int) for k in ("h", "w", "x", "y")) or \
                grid["x"] + grid["w"] > 24:
            c.error(pwhere, f"gridPos {grid}: want h, w, x, y within 24 columns")
        if not isinstance(panel.get("title"), str) or not panel["title"].strip():
            c.error(pwhere, "no title")
        if panel.get("type") == "row":
            continue
        count += 1
        if panel.get("type") in UNIT_PANELS and \
                not ((panel.get("fieldConfig") or {}).get("defaults") or {}).get("unit"):
            c.error(pwhere, "no unit (fieldConfig.defaults.unit)")
        targets = panel.get("targets") or []
        if not targets:
            c.error(pwhere, "no targets")
        refs = [t.get("refId") for t in targets if isinstance(t, dict)]
        if len(set(refs)) != len(targets):
            c.error(pwhere, f"refIds {refs}: want one distinct refId per target")
        for target in targets:
            for item in (panel, target):
                uid = (item.get("datasource") or {}).get("uid") \
                    if isinstance(item.get("datasource"), dict) else item.get("datasource")
                if uid != "${datasource}":
                    c.error(pwhere, f"datasource {uid!r}: want ${{datasource}}, the variable")
            expr = target.get("expr") if isinstance(target, dict) else None
            if not isinstance(expr, str) or not expr.strip():
                c.error(pwhere, f"target {target.get('refId') if isinstance(target, dict) else ''}"
                                ": no expr")
            else:
                check_promql(c, f"{pwhere} {target.get('refId')}", expr)
    if not count:
        c.error(where, "no panels")
    return count


def check_grafana(c, grafana_dir):
    """The dashboard, and the kustomization that makes it a ConfigMap for Grafana's sidecar.
    Returns the number of panels."""
    dashboard = grafana_dir / "shapeid-dashboard.json"
    count = check_dashboard(c, dashboard)
    for file, doc in load_docs(c, grafana_dir, "grafana/"):
        if not isinstance(doc, dict) or doc.get("kind") != "Kustomization":
            c.error(file, "want only a Kustomization here")
            continue
        check_kustomization(c, grafana_dir, file, doc, "grafana/")
        files = []
        for generator in doc.get("configMapGenerator") or []:
            for entry in generator.get("files") or []:
                source = str(entry).split("=", 1)[-1]
                if not (grafana_dir / source).is_file():
                    c.error(file, f"configMapGenerator file {source} does not exist")
                files.append(source)
            labels = dict(((doc.get("generatorOptions") or {}).get("labels") or {}),
                          **((generator.get("options") or {}).get("labels") or {}))
            if labels.get(DASHBOARD_LABEL[0]) != DASHBOARD_LABEL[1]:
                c.error(file, f"ConfigMap {generator.get('name')} lacks the label "
                              f"{DASHBOARD_LABEL[0]}: \"{DASHBOARD_LABEL[1]}\" that Grafana's "
                              "sidecar looks for")
        if dashboard.name not in files:
            c.error(file, f"no configMapGenerator for {dashboard.name}")
    return count


def configmap_data(path):
    try:
        for doc in yaml.safe_load_all(path.read_text()):
            if isinstance(doc, dict) and doc.get("kind") == "ConfigMap":
                return {k: str(v) for k, v in (doc.get("data") or {}).items()}
    except (OSError, yaml.YAMLError):
        pass  # reported by check_k8s
    return {}


def check_copies(c, base, scaled):
    """k8s/scaled/ repeats k8s/ (kustomize reads no single file from outside its directory):
    the copies must stay identical, the settings the same but for the store's."""
    for name in ("service.yaml", "secret.yaml"):
        if not (base / name).is_file() or not (scaled / name).is_file() or \
                (base / name).read_text() != (scaled / name).read_text():
            c.error(f"scaled/{name}", f"is not a copy of k8s/{name}: change both")
    one = configmap_data(base / "configmap.yaml")
    many = configmap_data(scaled / "configmap.yaml")
    if "SHAPEID_DATA_DIR" in many:
        c.error("scaled/configmap.yaml", "SHAPEID_DATA_DIR: the replicas keep nothing locally")
    for key in sorted((one.keys() | many.keys()) - STORE_SETTINGS - {"SHAPEID_DATA_DIR"}):
        if one.get(key) != many.get(key):
            c.error("scaled/configmap.yaml", f"{key} is {many.get(key)!r} here but "
                                             f"{one.get(key)!r} in k8s/configmap.yaml")


def check_dev_postgres(c, dev_dir, stores, secret_refs):
    """The dev-only PostgreSQL: reachable at SHAPEID_STORE's host and port, and logging in
    with the Secret keys the replicas read."""
    label = "scaled/dev-postgres/"
    docs = load_docs(c, dev_dir, label)
    services, pods = [], []
    for file, doc in docs:
        kind = doc.get("kind") if isinstance(doc, dict) else None
        if kind == "Kustomization":
            check_kustomization(c, dev_dir, file, doc, label)
        elif kind == "Service":
            services.append(doc)
        elif kind == "StatefulSet":
            template = ((doc.get("spec") or {}).get("template") or {})
            pods.append(((template.get("metadata") or {}).get("labels") or {},
                         (template.get("spec") or {}).get("containers") or []))
        else:
            c.error(file, f"unexpected kind {kind!r}")
    for service in services:
        selector = (service.get("spec") or {}).get("selector")
        if not any(matches(selector, labels) for labels, _ in pods):
            c.error(f"{label} Service", f"selector {selector} matches no StatefulSet's pods")
    addresses = {((s.get("metadata") or {}).get("name"), p.get("port"))
                 for s in services for p in (s.get("spec") or {}).get("ports") or []}
    for store in stores:
        if (store["host"], int(store["port"] or 5432)) not in addresses:
            c.error(label, f"SHAPEID_STORE's {store['host']}:{store['port'] or 5432} is not "
                           f"its Service {sorted(addresses, key=str)}")
    for _, containers in pods:
        for container in containers:
            for var in container.get("env") or []:
                ref = (var.get("valueFrom") or {}).get("secretKeyRef")
                if "PASSWORD" in var.get("name", "") and ref is None:
                    c.error(label, f"{var.get('name')} is not from the Secret")
                if ref is not None and (ref.get("name"), ref.get("key")) not in secret_refs:
                    c.error(label, f"{var.get('name')} reads {ref}, which the replicas do not")
    return len(docs)


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
        unknown = {k for k in env if k.startswith("SHAPEID_")} - SERVER_SETTINGS
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


def read_dockerfile(path):
    """The runtime stage's USER, EXPOSE'd ports and SHAPEID_* ENV defaults."""
    image = {"uid": None, "ports": set(), "data_dir": None, "listen": ""}
    lines = path.read_text().replace("\\\n", " ").splitlines()
    for line in lines:
        words = line.split()
        if not words:
            continue
        instruction = words[0].upper()
        if instruction == "FROM":
            image = {"uid": None, "ports": set(), "data_dir": None, "listen": ""}
        elif instruction == "USER":
            user = words[1].split(":")[0]
            image["uid"] = int(user) if user.isdigit() else user
        elif instruction == "EXPOSE":
            image["ports"] |= {int(p.split("/")[0]) for p in words[1:]}
        elif instruction == "ENV":
            for word in words[1:]:
                key, _, value = word.partition("=")
                if key == "SHAPEID_DATA_DIR":
                    image["data_dir"] = value
                elif key == "SHAPEID_LISTEN":
                    image["listen"] = value
    return image


def main():
    deploy = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent)
    c = Checker()
    main_cc = deploy.parent / "server" / "main.cc"
    if main_cc.is_file():
        flags = ABSL_FLAG.findall(main_cc.read_text())
        SERVER_SETTINGS.clear()
        SERVER_SETTINGS.update(f"SHAPEID_{flag.upper()}" for flag in flags)
    readme = (deploy / "README.md").read_text() if (deploy / "README.md").is_file() else ""
    image = read_dockerfile(deploy / "Dockerfile")
    if not isinstance(image["uid"], int) or image["uid"] == 0:
        c.error("Dockerfile", f"USER must be a non-zero numeric uid, got {image['uid']!r}")
    if 50051 not in image["ports"]:
        c.error("Dockerfile", "EXPOSE 50051 missing")
    count, _, _ = check_k8s(c, deploy / "k8s", image)
    scaled, stores, secret_refs = check_k8s(c, deploy / "k8s" / "scaled", image, True, readme)
    check_copies(c, deploy / "k8s", deploy / "k8s" / "scaled")
    dev = check_dev_postgres(c, deploy / "k8s" / "scaled" / "dev-postgres", stores, secret_refs)
    check_compose(c, deploy / "compose.yaml", image)
    check_compose(c, deploy / "compose.postgres.yaml", image, scaled=True)
    panels = check_grafana(c, deploy / "grafana")
    for problem in c.problems:
        print(f"check_manifests: {problem}")
    print(f"check_manifests: Kubernetes documents: {count} in k8s/, {scaled} in k8s/scaled/, "
          f"{dev} in k8s/scaled/dev-postgres/; {panels} dashboard panels; compose.yaml, "
          f"compose.postgres.yaml, grafana/: "
          f"{'OK' if not c.problems else f'{len(c.problems)} problems'}")
    return 1 if c.problems else 0


if __name__ == "__main__":
    sys.exit(main())
