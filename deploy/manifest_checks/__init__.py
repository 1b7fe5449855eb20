"""The checks behind deploy/check_manifests.py (its docstring says what they cover), one module
per concern:

    checker          the problem list; quantities, selectors, loading YAML, kustomizations
    settings         the server's SHAPEID_* settings (from server/main.cc), ports, store URI
    dockerfile       the Dockerfile's USER, EXPOSEd ports and ENV defaults
    k8s_schema       the Kubernetes field names and kinds these manifests may use
    k8s_deployment   a Deployment, its pod and container
    k8s              a manifest directory's objects and their cross-references; the copies
    compose          compose.yaml and compose.postgres.yaml
    grafana          the dashboard's JSON and PromQL against the server's metrics (METRICS)

Standard library and python3-yaml only.
"""

from .checker import Checker
from .compose import check_compose
from .dockerfile import check_image, read_dockerfile
from .grafana import check_grafana
from .k8s import check_copies, check_dev_postgres, check_k8s
from .settings import read_server_settings


def plural(count, noun):
    """'1 problem', '2 problems'."""
    return f"{count} {noun}" if count == 1 else f"{count} {noun}s"


def run(deploy):
    """Checks the deploy directory `deploy` (a pathlib.Path); server/main.cc is read from its
    parent. Prints one line per problem and a summary; returns the exit code (1 on any)."""
    c = Checker()
    main_cc = deploy.parent / "server" / "main.cc"
    if not read_server_settings(main_cc):
        print(f"check_manifests: {main_cc} not found: settings are not checked against the "
              f"server's flags")
    readme = (deploy / "README.md").read_text() if (deploy / "README.md").is_file() else ""
    image = read_dockerfile(c, deploy / "Dockerfile")
    check_image(c, image)
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
          f"{'OK' if not c.problems else plural(len(c.problems), 'problem')}")
    return 1 if c.problems else 0
