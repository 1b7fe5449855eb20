"""The problem list every check appends to, and the helpers the Kubernetes, compose and Grafana
checks share: quantities, label selectors, loading a directory's YAML, its kustomization."""

import re

import yaml

from .k8s_schema import KUSTOMIZATION

QUANTITY = re.compile(r"^([0-9.]+)(m|k|M|G|T|P|E|Ki|Mi|Gi|Ti|Pi|Ei)?$")
SCALE = {None: 1, "m": 1e-3, "k": 1e3, "M": 1e6, "G": 1e9, "T": 1e12, "P": 1e15, "E": 1e18,
         "Ki": 2**10, "Mi": 2**20, "Gi": 2**30, "Ti": 2**40, "Pi": 2**50, "Ei": 2**60}


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


def matches(selector, labels):
    """A non-empty matchLabels selector that the labels satisfy."""
    return bool(selector) and isinstance(selector, dict) and \
        all(labels.get(k) == v for k, v in selector.items())


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
