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
names among those the server exports (METRICS in manifest_checks/grafana.py); its
kustomization for Grafana's sidecar.

    /usr/bin/python3 deploy/check_manifests.py [DEPLOY_DIR]

Needs python3-yaml (Debian). Prints one line per problem and exits 1 if there is any.
The checks are in the package manifest_checks/ beside this file, one module per concern.
"""

import pathlib
import sys

# The package beside this file, whatever the working directory or DEPLOY_DIR.
sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
import manifest_checks  # noqa: E402


def main():
    deploy = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else pathlib.Path(__file__).parent)
    return manifest_checks.run(deploy)


if __name__ == "__main__":
    sys.exit(main())
