"""The Grafana dashboard (grafana/): valid JSON, its variables and panels, every metric and label
its PromQL names among those the server exports (METRICS); and the kustomization that makes it
a ConfigMap for Grafana's sidecar."""

import json
import re

from .checker import check_kustomization, load_docs

# The metrics shapeid-server exports (server/ops/metrics.cc, docs/operations.md): name -> (type,
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
