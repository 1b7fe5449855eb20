"""A directory of Kubernetes manifests (k8s/, k8s/scaled/, k8s/scaled/dev-postgres/): its
documents and kustomization, ConfigMaps, claims, Secrets, Services and disruption budgets and
their cross-references to the Deployments; and the copies k8s/scaled/ keeps of k8s/ files."""

import re

import yaml

from .checker import check_kustomization, load_docs, matches, quantity
from .k8s_deployment import check_deployment, check_meta
from .k8s_schema import ACCESS_MODES, KINDS, PDB_SPEC, PVC_SPEC, SECRET, SERVICE_PORT, SERVICE_SPEC
from .settings import STORE_SETTINGS, check_store_uri, check_values, unknown_settings

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
            unknown = unknown_settings(data)
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
