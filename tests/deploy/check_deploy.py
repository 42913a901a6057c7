#!/usr/bin/python3
"""Checks deploy/kubernetes and deploy/apptainer without a cluster or network.

Kubernetes: every document against the fields its kind/apiVersion requires
and allows (a small structural schema of the Kubernetes API for the kinds we
ship: unknown keys are typos, missing keys are refused by the API server),
then the references between them: selectors match the pod labels, a
Service's targetPort names a container port of the pods it selects, volume
mounts name a volume or a claim template, secretKeyRef names a Secret and a
key it defines, the worker dials the Service's worker port, and every option
on a cellflow command line is one the built program accepts (its --help).
Apptainer: the definition's headers and sections, and that it installs the
Debian packages the Dockerfile does.

  check_deploy.py REPO_ROOT BIN_DIR
Needs /usr/bin/python3 with python3-yaml (scripts/install-deps.sh).
"""
import base64
import pathlib
import re
import subprocess
import sys

import yaml

errors = []


def error(where, message):
    errors.append(f"{where}: {message}")


DNS1123 = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")
LABEL_VALUE = re.compile(r"^(([A-Za-z0-9][-A-Za-z0-9_.]*)?[A-Za-z0-9])?$")
QUANTITY = re.compile(r"^[0-9]+(\.[0-9]+)?(m|k|Ki|M|Mi|G|Gi|T|Ti)?$")


# A schema node: ("map", {key: (required, node)}), ("list", node), or a leaf
# type: str, int, bool, "quantity", "port", "name", "labels", "any".
def m(fields):
    return ("map", fields)


def req(node):
    return (True, node)


def opt(node):
    return (False, node)


LABELS = "labels"
METADATA = m({
    "name": req("name"),
    "namespace": opt("name"),
    "labels": opt(LABELS),
    "annotations": opt(LABELS),
})
TEMPLATE_METADATA = m({"labels": req(LABELS), "annotations": opt(LABELS)})
RESOURCES = m({"requests": opt(("dict", "quantity")), "limits": opt(("dict", "quantity"))})
PROBE = m({
    "grpc": opt(m({"port": req("port"), "service": opt(str)})),
    "tcpSocket": opt(m({"port": req("port")})),
    "exec": opt(m({"command": req(("list", str))})),
    "initialDelaySeconds": opt(int),
    "periodSeconds": opt(int),
    "timeoutSeconds": opt(int),
    "failureThreshold": opt(int),
    "successThreshold": opt(int),
})
ENV_VAR = m({
    "name": req(str),
    "value": opt(str),
    "valueFrom": opt(m({
        "secretKeyRef": opt(m({"name": req("name"), "key": req(str), "optional": opt(bool)})),
        "configMapKeyRef": opt(m({"name": req("name"), "key": req(str)})),
        "fieldRef": opt(m({"fieldPath": req(str)})),
    })),
})
CONTAINER = m({
    "name": req("name"),
    "image": req(str),
    "imagePullPolicy": opt(("enum", {"Always", "IfNotPresent", "Never"})),
    "command": opt(("list", str)),
    "args": opt(("list", str)),
    "env": opt(("list", ENV_VAR)),
    "ports": opt(("list", m({
        "name": opt("name"),
        "containerPort": req("port"),
        "protocol": opt(("enum", {"TCP", "UDP", "SCTP"})),
    }))),
    "readinessProbe": opt(PROBE),
    "livenessProbe": opt(PROBE),
    "startupProbe": opt(PROBE),
    "resources": opt(RESOURCES),
    "volumeMounts": opt(("list", m({"name": req("name"), "mountPath": req(str), "readOnly": opt(bool),
                                    "subPath": opt(str)}))),
    "securityContext": opt(m({"readOnlyRootFilesystem": opt(bool), "allowPrivilegeEscalation": opt(bool),
                              "runAsNonRoot": opt(bool), "runAsUser": opt(int)})),
})
POD_SPEC = m({
    "containers": req(("list", CONTAINER)),
    "terminationGracePeriodSeconds": opt(int),
    "securityContext": opt(m({"runAsNonRoot": opt(bool), "runAsUser": opt(int), "runAsGroup": opt(int),
                              "fsGroup": opt(int)})),
    "volumes": opt(("list", m({
        "name": req("name"),
        "emptyDir": opt(("dict", "any")),
        "secret": opt(m({"secretName": req("name"), "defaultMode": opt(int)})),
        "persistentVolumeClaim": opt(m({"claimName": req("name")})),
    }))),
    "serviceAccountName": opt("name"),
    "nodeSelector": opt(LABELS),
})
POD_TEMPLATE = m({"metadata": req(TEMPLATE_METADATA), "spec": req(POD_SPEC)})
SELECTOR = m({"matchLabels": req(LABELS)})
PVC_SPEC = m({
    "accessModes": req(("list", ("enum", {"ReadWriteOnce", "ReadOnlyMany", "ReadWriteMany",
                                         "ReadWriteOncePod"}))),
    "resources": req(m({"requests": req(m({"storage": req("quantity")}))})),
    "storageClassName": opt(str),
})

SCHEMAS = {
    ("v1", "Service"): m({
        "apiVersion": req(str), "kind": req(str), "metadata": req(METADATA),
        "spec": req(m({
            "type": opt(("enum", {"ClusterIP", "NodePort", "LoadBalancer"})),
            "clusterIP": opt(str),
            "selector": req(LABELS),
            "ports": req(("list", m({
                "name": opt("name"), "port": req("port"), "targetPort": opt("port_or_name"),
                "protocol": opt(("enum", {"TCP", "UDP", "SCTP"})), "nodePort": opt("port"),
            }))),
        })),
    }),
    ("v1", "Secret"): m({
        "apiVersion": req(str), "kind": req(str), "metadata": req(METADATA),
        "type": opt(str), "data": opt(("dict", str)), "stringData": opt(("dict", str)),
    }),
    ("apps/v1", "StatefulSet"): m({
        "apiVersion": req(str), "kind": req(str), "metadata": req(METADATA),
        "spec": req(m({
            "serviceName": req("name"),
            "replicas": opt(int),
            "selector": req(SELECTOR),
            "template": req(POD_TEMPLATE),
            "volumeClaimTemplates": opt(("list", m({"metadata": req(m({"name": req("name")})),
                                                    "spec": req(PVC_SPEC)}))),
            "podManagementPolicy": opt(("enum", {"OrderedReady", "Parallel"})),
        })),
    }),
    ("apps/v1", "Deployment"): m({
        "apiVersion": req(str), "kind": req(str), "metadata": req(METADATA),
        "spec": req(m({
            "replicas": opt(int),
            "selector": req(SELECTOR),
            "template": req(POD_TEMPLATE),
            "strategy": opt(("dict", "any")),
        })),
    }),
    ("kustomize.config.k8s.io/v1beta1", "Kustomization"): m({
        "apiVersion": req(str), "kind": req(str), "resources": req(("list", str)),
        "namespace": opt("name"), "images": opt(("list", ("dict", "any"))),
    }),
}


def check(where, value, node):
    if node == "any":
        return
    if node == "name":
        if not isinstance(value, str) or not DNS1123.match(value) or len(value) > 63:
            error(where, f"{value!r} is not a DNS-1123 label")
        return
    if node == "port":
        if not isinstance(value, int) or isinstance(value, bool) or not 1 <= value <= 65535:
            error(where, f"{value!r} is not a port number")
        return
    if node == "port_or_name":
        if isinstance(value, str):
            check(where, value, "name")
        else:
            check(where, value, "port")
        return
    if node == "quantity":
        if not isinstance(value, (str, int)) or not QUANTITY.match(str(value)):
            error(where, f"{value!r} is not a quantity")
        return
    if node == LABELS:
        if not isinstance(value, dict):
            error(where, "labels must be a map")
            return
        for k, v in value.items():
            if not isinstance(v, str) or not LABEL_VALUE.match(v) or len(v) > 63:
                error(f"{where}.{k}", f"{v!r} is not a label value (a string)")
        return
    if node in (str, int, bool):
        if not isinstance(value, node) or (node is int and isinstance(value, bool)):
            error(where, f"{value!r} is not a {node.__name__}")
        return
    kind = node[0]
    if kind == "enum":
        if value not in node[1]:
            error(where, f"{value!r} is not one of {sorted(node[1])}")
    elif kind == "list":
        if not isinstance(value, list) or not value:
            error(where, "must be a non-empty list")
            return
        for i, item in enumerate(value):
            check(f"{where}[{i}]", item, node[1])
    elif kind == "dict":
        if not isinstance(value, dict):
            error(where, "must be a map")
            return
        for k, v in value.items():
            check(f"{where}.{k}", v, node[1])
    elif kind == "map":
        if not isinstance(value, dict):
            error(where, "must be a map")
            return
        for key, (required, _) in node[1].items():
            if required and key not in value:
                error(where, f"missing required field {key}")
        for key, item in value.items():
            if key not in node[1]:
                error(where, f"unknown field {key}")
                continue
            check(f"{where}.{key}", item, node[1][key][1])


def help_options(program):
    text = subprocess.run([program, "--help"], capture_output=True, text=True, timeout=30).stdout
    return set(re.findall(r"(--[a-z0-9][a-z0-9-]*)", text))


def check_command(where, command, bin_dir):
    program = pathlib.Path(bin_dir) / command[0]
    if not program.exists():
        error(where, f"{command[0]} is not a cellflow program")
        return
    known = help_options(program)
    for argument in command[1:]:
        if argument.startswith("--") and argument.split("=", 1)[0] not in known:
            error(where, f"{command[0]} has no option {argument.split('=', 1)[0]}")


def check_kubernetes(directory, bin_dir):
    documents = []
    for path in sorted(directory.glob("*.yaml")):
        for index, document in enumerate(yaml.safe_load_all(path.read_text())):
            if document is None:
                continue
            where = f"{path.name}[{index}]"
            key = (document.get("apiVersion"), document.get("kind"))
            if key not in SCHEMAS:
                error(where, f"unexpected apiVersion/kind {key}")
                continue
            check(where, document, SCHEMAS[key])
            documents.append((where, path.name, document))
    by_kind = {}
    for where, file_name, document in documents:
        by_kind.setdefault(document["kind"], []).append((where, file_name, document))
    for kind in ("Service", "Secret", "StatefulSet", "Deployment"):
        if kind not in by_kind:
            error(str(directory), f"no {kind}")
    if errors:
        return  # the references below assume the structure

    kustomization = by_kind.get("Kustomization", [])
    listed = set(kustomization[0][2]["resources"]) if kustomization else set()
    for where, file_name, document in documents:
        if document["kind"] != "Kustomization" and file_name not in listed:
            error(where, f"{file_name} is not listed in kustomization.yaml")
    secrets = {}
    for where, _, secret in by_kind["Secret"]:
        keys = set(secret.get("stringData", {})) | set(secret.get("data", {}))
        for k, v in secret.get("data", {}).items():
            try:
                base64.b64decode(v, validate=True)
            except ValueError:
                error(f"{where}.data.{k}", "not base64")
        secrets[secret["metadata"]["name"]] = keys
    workloads = by_kind["StatefulSet"] + by_kind["Deployment"]
    pods = []  # (labels, container port names -> numbers)
    for where, _, workload in workloads:
        spec = workload["spec"]
        labels = spec["template"]["metadata"]["labels"]
        for k, v in spec["selector"]["matchLabels"].items():
            if labels.get(k) != v:
                error(f"{where}.spec.selector", f"{k}={v} does not match the pod template's labels")
        volumes = {v["name"] for v in spec["template"]["spec"].get("volumes", [])}
        volumes |= {c["metadata"]["name"] for c in spec.get("volumeClaimTemplates", [])}
        ports = {}
        for i, container in enumerate(spec["template"]["spec"]["containers"]):
            cwhere = f"{where}.containers[{i}]"
            for mount in container.get("volumeMounts", []):
                if mount["name"] not in volumes:
                    error(cwhere, f"volumeMount {mount['name']} names no volume or claim template")
            for env in container.get("env", []):
                ref = env.get("valueFrom", {}).get("secretKeyRef")
                if ref and ref["key"] not in secrets.get(ref["name"], set()):
                    error(cwhere, f"env {env['name']}: no Secret {ref['name']} with key {ref['key']}")
                if not ref and "value" not in env:
                    error(cwhere, f"env {env['name']} has neither value nor valueFrom")
            for port in container.get("ports", []):
                if "name" in port:
                    ports[port["name"]] = port["containerPort"]
            for probe in ("readinessProbe", "livenessProbe", "startupProbe"):
                grpc_port = container.get(probe, {}).get("grpc", {}).get("port")
                if grpc_port is not None and grpc_port not in ports.values():
                    error(cwhere, f"{probe} checks port {grpc_port}, which the container does not open")
            command = container.get("command", []) + container.get("args", [])
            if command:
                check_command(cwhere, command, bin_dir)
        pods.append((labels, ports))
        if workload["kind"] == "StatefulSet":
            names = {s["metadata"]["name"] for _, _, s in by_kind["Service"]}
            if spec["serviceName"] not in names:
                error(f"{where}.spec.serviceName", f"no Service {spec['serviceName']}")
            if not spec.get("volumeClaimTemplates"):
                error(f"{where}.spec", "the server's data needs a volumeClaimTemplate")
    services = {}
    for where, _, service in by_kind["Service"]:
        selector = service["spec"]["selector"]
        selected = [ports for labels, ports in pods if all(labels.get(k) == v for k, v in selector.items())]
        if not selected:
            error(where, f"selector {selector} selects no pod template")
            continue
        numbers = {}
        for port in service["spec"]["ports"]:
            target = port.get("targetPort", port["port"])
            if isinstance(target, str) and not any(target in p for p in selected):
                error(where, f"targetPort {target} is no container port of the selected pods")
            numbers[port["port"]] = target
        services[service["metadata"]["name"]] = numbers
    # The worker dials host:port of the Service's worker port.
    for where, _, deployment in by_kind["Deployment"]:
        for container in deployment["spec"]["template"]["spec"]["containers"]:
            for argument in container.get("command", []) + container.get("args", []):
                if argument.startswith("--server="):
                    host, _, port = argument.split("=", 1)[1].rpartition(":")
                    if host not in services or int(port) not in services[host]:
                        error(where, f"--server={host}:{port} is not a port of a Service")


def apt_packages(text):
    """The package names of every `apt-get install` in a Dockerfile or definition."""
    joined = text.replace("\\\n", " ")
    packages = []
    for line in joined.splitlines():
        if "apt-get install" in line:
            words = line.split("apt-get install", 1)[1].split("&&")[0].split()
            packages.append({w for w in words if not w.startswith("-")})
    return packages


def check_apptainer(definition, dockerfile):
    text = definition.read_text()
    where = definition.name
    stages = re.findall(r"^Bootstrap:\s*(\S+)\s*\nFrom:\s*(\S+)", text, re.M)
    if not stages or any(b != "docker" for b, _ in stages):
        error(where, "every stage needs 'Bootstrap: docker' and 'From:'")
    if not all(f.startswith("debian:bookworm") for _, f in stages):
        error(where, "the image must build from Debian 12 (debian:bookworm)")
    known = {"files", "post", "environment", "runscript", "test", "labels", "help", "setup", "startscript"}
    for section in re.findall(r"^%([a-z]+)", text, re.M):
        if section not in known:
            error(where, f"unknown section %{section}")
    for section in ("post", "runscript", "environment", "files"):
        if not re.search(rf"^%{section}\b", text, re.M):
            error(where, f"no %{section}")
    ours, theirs = apt_packages(text), apt_packages(dockerfile.read_text())
    if len(ours) != 2 or len(theirs) != 2:
        error(where, f"expected a build and a runtime apt-get install in both, got {len(ours)} and {len(theirs)}")
    else:
        for stage, a, b in (("build", ours[0], theirs[0]), ("runtime", ours[1], theirs[1])):
            if a != b:
                error(where, f"{stage} packages differ from the Dockerfile's: only here {sorted(a - b)}, "
                             f"only there {sorted(b - a)}")


# Mistakes the checks must catch: (file, text, replacement, expected error).
MUTATIONS = [
    ("server.yaml", "    - name: workers\n      port: 50052\n      targetPort: workers",
     "    - name: workers\n      port: 50052\n      targetPort: worker", "targetPort worker"),
    ("server.yaml", "  replicas: 1", "  replica: 1", "unknown field replica"),
    ("server.yaml", "- --grace-s=30", "- --grace-seconds=30", "no option --grace-seconds"),
    ("server.yaml", "storage: 20Gi", "storage: twenty", "is not a quantity"),
    ("server.yaml", "              mountPath: /var/lib/cellflow", "              mountpath: /var/lib/cellflow",
     "missing required field mountPath"),
    ("worker.yaml", "key: token", "key: worker-token", "no Secret cellflow-worker-token with key worker-token"),
    ("worker.yaml", "--server=cellflow-server:50052", "--server=cellflow-server:50053", "is not a port of a Service"),
    ("worker.yaml", "      app.kubernetes.io/component: worker\n  template",
     "      app.kubernetes.io/component: workers\n  template", "does not match the pod template"),
]


def self_test(root, bin_dir):
    """Each mutation of the shipped manifests is caught with the expected error."""
    import shutil
    import tempfile
    failures = 0
    for file_name, text, replacement, expected in MUTATIONS:
        with tempfile.TemporaryDirectory() as tmp:
            copy = pathlib.Path(tmp) / "kubernetes"
            shutil.copytree(root / "deploy" / "kubernetes", copy)
            content = (copy / file_name).read_text()
            if text not in content:
                print(f"self-test: {file_name} no longer contains {text!r}")
                failures += 1
                continue
            (copy / file_name).write_text(content.replace(text, replacement, 1))
            errors.clear()
            check_kubernetes(copy, bin_dir)
            if not any(expected in e for e in errors):
                print(f"self-test: {file_name} with {replacement!r}: expected an error with {expected!r}, "
                      f"got {errors}")
                failures += 1
    errors.clear()
    print(f"self-test: {len(MUTATIONS) - failures} of {len(MUTATIONS)} mutations caught")
    return failures


def main():
    root, bin_dir = pathlib.Path(sys.argv[1]), sys.argv[2]
    if self_test(root, bin_dir):
        return 1
    check_kubernetes(root / "deploy" / "kubernetes", bin_dir)
    check_apptainer(root / "deploy" / "apptainer" / "cellflow.def", root / "deploy" / "Dockerfile")
    for e in errors:
        print("error:", e)
    if errors:
        return 1
    print("deploy/kubernetes and deploy/apptainer: ok")
    return 0


if __name__ == "__main__":
    sys.exit(main())
