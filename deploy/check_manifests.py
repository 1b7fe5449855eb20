#!/usr/bin/python3
"""Offline check of deploy/compose.yaml, deploy/k8s/*.yaml and their agreement with the Dockerfile.

No cluster or schema download is available offline (CI reaches Debian's mirror only), and
`kubectl apply --dry-run=client` cannot run without one: even client-side dry runs ask an API
server for discovery (this machine image has Google Cloud SDK's kubectl, which fails there with
"connection refused"; `kubectl kustomize` does work offline and test_container.sh runs it when
kubectl is present). So this does by hand what a client-side dry run would catch here:
YAML that parses, apiVersion/kind/metadata.name, field names (against the subset of the API
schema these kinds use: a typo such as `readinesProbe` is an error, as kubectl's strict field
validation makes it), value types, and every cross-reference: selectors and labels, volume mounts
and volumes, ConfigMap and PersistentVolumeClaim names, probe and Service ports, the data
directory, the image's user, port and volume.

    /usr/bin/python3 deploy/check_manifests.py [DEPLOY_DIR]

Needs python3-yaml (Debian). Prints one line per problem and exits 1 if there is any.
"""

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
KINDS = {"ConfigMap": "v1", "Service": "v1", "PersistentVolumeClaim": "v1",
         "Secret": "v1", "Deployment": "apps/v1"}
SECRET = {"apiVersion", "kind", "metadata", "type", "data", "stringData", "immutable"}
COMPOSE_TOP = {"name", "services", "volumes", "networks", "configs", "secrets", "version",
               "include"}
# The fields of a Compose service these checks understand; others are reported so that a typo
# is not silently ignored (docker compose rejects unknown service fields).
COMPOSE_SERVICE = {"build", "image", "restart", "ports", "environment", "env_file", "volumes",
                   "read_only", "tmpfs", "cap_drop", "cap_add", "security_opt",
                   "stop_grace_period", "stop_signal", "healthcheck", "command", "entrypoint",
                   "user", "deploy", "logging", "networks", "container_name", "labels",
                   "depends_on", "init", "ulimits", "mem_limit", "cpus", "profiles"}
# The server's settings: SHAPEID_<FLAG> for every ABSL_FLAG in server/main.cc (read there, so a
# new flag needs no change here); this list only when the deploy folder is checked on its own.
SERVER_SETTINGS = {"SHAPEID_LISTEN", "SHAPEID_DATA_DIR", "SHAPEID_MAX_POINTS_PER_CLOUD",
                   "SHAPEID_MAX_MESSAGE_BYTES", "SHAPEID_SET_ASIDE_DAMAGED",
                   "SHAPEID_SHUTDOWN_GRACE_SECONDS"}
ABSL_FLAG = re.compile(r"ABSL_FLAG\(\s*[\w:]+\s*,\s*(\w+)\s*,")
QUANTITY = re.compile(r"^([0-9.]+)(m|k|M|G|T|P|E|Ki|Mi|Gi|Ti|Pi|Ei)?$")
SCALE = {None: 1, "m": 1e-3, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12, "P": 1e15, "E": 1e18,
         "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "Pi": 2**50, "Ei": 2**60}
DURATION = re.compile(r"^([0-9]+(\.[0-9]+)?(us|ms|s|m|h))+$")


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

    env = {}
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
        if "value" in var:
            if not isinstance(var["value"], str):
                c.error(f"{where}.env[{i}]", f"value of {var['name']} must be a string")
            env[var["name"]] = var["value"]
        ref = (var.get("valueFrom") or {}).get("configMapKeyRef")
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
    return container, port_numbers, port_names, env, mounts


def check_deployment(c, where, doc, configmaps, claims, image):
    spec = c.fields(f"{where} spec", doc.get("spec"), DEPLOYMENT_SPEC)
    if spec.get("replicas", 1) != 1:
        c.error(where, "replicas must be 1: one server per data directory")
    if (spec.get("strategy") or {}).get("type") != "Recreate":
        c.error(where, "strategy.type must be Recreate: the old server must release the "
                       "volume before the new one starts")
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
        if "persistentVolumeClaim" in volume and claim not in claims:
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

    containers = pod.get("containers") or []
    if len(containers) != 1:
        c.error(where, f"want one container, got {len(containers)}")
    result = {"labels": labels, "ports": set(), "port_names": set()}
    for i, container in enumerate(containers):
        cwhere = f"{where} containers[{i}]"
        container, numbers, names, env, mounts = check_container(
            c, cwhere, container, set(volumes), configmaps)
        result["ports"] |= numbers
        result["port_names"] |= names
        unknown = {k for k in env if k.startswith("SHAPEID_")} - SERVER_SETTINGS
        if unknown:
            c.error(cwhere, f"unknown settings {sorted(unknown)}")
        data_dir = env.get("SHAPEID_DATA_DIR", image.get("data_dir"))
        mount = mounts.get(data_dir)
        if mount is None:
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
        if drain.isdigit() and int(drain) >= grace:
            c.error(cwhere, f"SHAPEID_SHUTDOWN_GRACE_SECONDS={drain} must be below "
                            f"terminationGracePeriodSeconds={grace}")
    return result


def check_service(c, where, doc, deployments):
    spec = c.fields(f"{where} spec", doc.get("spec"), SERVICE_SPEC)
    selector = spec.get("selector") or {}
    targets = [d for d in deployments
               if selector and all(d["labels"].get(k) == v for k, v in selector.items())]
    if not targets:
        c.error(where, f"selector {selector} matches no Deployment's pods")
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


def check_k8s(c, k8s_dir, image):
    docs = []  # (file, document)
    for path in sorted(k8s_dir.glob("*.yaml")):
        try:
            for doc in yaml.safe_load_all(path.read_text()):
                if doc is not None:
                    docs.append((path.name, doc))
        except yaml.YAMLError as e:
            c.error(path.name, f"YAML: {e}")
    objects = {}
    for file, doc in docs:
        if not isinstance(doc, dict):
            c.error(file, "a document is not a mapping")
            continue
        kind = doc.get("kind")
        if kind == "Kustomization":
            c.fields(file, doc, KUSTOMIZATION)
            listed = doc.get("resources") or []
            for resource in listed:
                if not (k8s_dir / resource).is_file():
                    c.error(file, f"resource {resource} does not exist")
            for path in sorted(k8s_dir.glob("*.yaml")):
                if path.name != file and path.name not in listed:
                    c.error(file, f"{path.name} is not in resources")
            continue
        where = f"{file} {kind}"
        c.require(file, doc, "apiVersion", "kind", "metadata")
        if kind not in KINDS:
            c.error(file, f"unexpected kind {kind!r}")
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
            unknown = {k for k in data if k.startswith("SHAPEID_")} - SERVER_SETTINGS
            if unknown:
                c.error(f"{file} ConfigMap", f"unknown settings {sorted(unknown)}")
            configmaps[name] = {k: str(v) for k, v in data.items()}
    claims = set()
    for (kind, name), (file, doc) in objects.items():
        if kind == "PersistentVolumeClaim":
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
    secrets = set()
    for (kind, name), (file, doc) in objects.items():
        if kind == "Secret":
            c.fields(f"{file} Secret", doc, SECRET)
            for key, value in (doc.get("stringData") or {}).items():
                if not isinstance(value, str):
                    c.error(f"{file} Secret", f"stringData.{key} must be a string")
            secrets.add(name)
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
    deployments = [check_deployment(c, f"{file} Deployment", doc, configmaps, claims, image)
                   for (kind, _), (file, doc) in objects.items() if kind == "Deployment"]
    if not deployments:
        c.error(str(k8s_dir), "no Deployment")
    for (kind, _), (file, doc) in objects.items():
        if kind == "Service":
            check_service(c, f"{file} Service", doc, deployments)
    for needed in ("ConfigMap", "Service", "PersistentVolumeClaim"):
        if not any(kind == needed for kind, _ in objects):
            c.error(str(k8s_dir), f"no {needed}")
    return len(docs)


def check_compose(c, path, image):
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
        if not service.get("ports"):
            c.error(swhere, "no published ports")
        for port in service.get("ports") or []:
            if not isinstance(port, (str, dict)):
                c.error(swhere, f"port {port!r}: write it as a quoted string")
        env = service.get("environment") or {}
        if isinstance(env, list):
            env = dict(e.split("=", 1) if "=" in e else (e, "") for e in env)
        for key, value in env.items():
            if not isinstance(value, str):
                c.error(swhere, f"environment {key}: {value!r}: quote it")
        unknown = {k for k in env if k.startswith("SHAPEID_")} - SERVER_SETTINGS
        if unknown:
            c.error(swhere, f"unknown settings {sorted(unknown)}")
        data_dir = env.get("SHAPEID_DATA_DIR", image.get("data_dir"))
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
    image = read_dockerfile(deploy / "Dockerfile")
    if not isinstance(image["uid"], int) or image["uid"] == 0:
        c.error("Dockerfile", f"USER must be a non-zero numeric uid, got {image['uid']!r}")
    if 50051 not in image["ports"]:
        c.error("Dockerfile", "EXPOSE 50051 missing")
    count = check_k8s(c, deploy / "k8s", image)
    check_compose(c, deploy / "compose.yaml", image)
    for problem in c.problems:
        print(f"check_manifests: {problem}")
    print(f"check_manifests: {count} Kubernetes documents and compose.yaml: "
          f"{'OK' if not c.problems else f'{len(c.problems)} problems'}")
    return 1 if c.problems else 0


if __name__ == "__main__":
    sys.exit(main())
