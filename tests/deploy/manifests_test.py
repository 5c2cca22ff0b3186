#!/usr/bin/env python3
"""The deployment files as far as this machine can run them (no Docker engine, no cluster):

- deploy/forestmapd.conf names every flag of serving, and forestmapd accepts it with every
  setting uncommented;
- deploy/compose.yaml is YAML and holds no password: PostgreSQL and forestmapd read Docker
  secrets, and the ports are published on loopback only;
- deploy/kubernetes/forestmapd.yaml is YAML: TLS from a Secret, metrics port and Prometheus
  annotations, a NetworkPolicy; its ConfigMap's forestmapd.conf, with the pod's variables, starts
  the built forestmapd beyond loopback with TLS, warning only of the plain-HTTP metrics port
  (which the ConfigMap explains), once the documented bootstrap command made a token in the same
  database, which then gates the calls; the probes' paths answer 200 on the metrics port.

Usage: manifests_test.py FORESTMAPD FORESTMAP (the built binaries)
"""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import tempfile
import time
import unittest
import urllib.request

import yaml

ROOT = pathlib.Path(__file__).resolve().parents[2]
FORESTMAPD, FORESTMAP = sys.argv[1:3] if len(sys.argv) >= 3 else ("", "")
CLEAN_ENV = {k: v for k, v in os.environ.items()
             if not k.startswith(("FORESTMAPD_", "FORESTMAP_"))}


def serve_flags():
    """The flags of serving, as `forestmapd --help` lists them (not --help, --version, --config)."""
    text = subprocess.run([FORESTMAPD, "--help"], capture_output=True, text=True, check=True).stdout
    options = text.split("Subcommands:")[0]
    flags = set(re.findall(r"^\s+(?:-\w, )?--([a-z][a-z0-9-]*)", options, re.M))
    return flags - {"help", "version", "config"}


def run(args, env, **kwargs):
    return subprocess.run(args, env={**CLEAN_ENV, **env}, capture_output=True, text=True,
                          timeout=60, **kwargs)


class ShippedConfigFile(unittest.TestCase):
    def test_names_every_flag_and_is_accepted_uncommented(self):
        text = (ROOT / "deploy/forestmapd.conf").read_text()
        settings = re.findall(r"^# ([a-z][a-z0-9-]*) = (.*)$", text, re.M)
        self.assertEqual({key for key, _ in settings}, serve_flags())
        first = {}
        for key, value in settings:
            first.setdefault(key, value)
        with tempfile.TemporaryDirectory() as tmp:
            conf = pathlib.Path(tmp, "forestmapd.conf")
            conf.write_text("".join(f"{k} = {v}\n" for k, v in first.items()))
            # Parsing checks every value; `token list` on a database of the test runs nothing else.
            result = run([FORESTMAPD, "--config", str(conf), "token", "list",
                          "--db", str(pathlib.Path(tmp, "x.db"))], {})
            self.assertEqual(result.returncode, 0, result.stderr)


class Compose(unittest.TestCase):
    def test_no_password_in_the_file(self):
        compose = yaml.safe_load((ROOT / "deploy/compose.yaml").read_text())
        services = compose["services"]
        text = json.dumps(compose)
        self.assertNotRegex(text, r"postgres(ql)?://[^@/\"]*:[^@/\"]*@", "a password in a URI")
        self.assertNotIn("POSTGRES_PASSWORD\"", text)
        self.assertEqual(services["postgres"]["environment"]["POSTGRES_PASSWORD_FILE"],
                         "/run/secrets/postgres_password")
        for name, service in services.items():
            for secret in service.get("secrets", []):
                self.assertIn(secret, compose["secrets"], name)
            for port in service.get("ports", []):
                self.assertTrue(port.startswith("127.0.0.1:"), f"{name} publishes {port}")
            if name.startswith("forestmapd"):
                env = service["environment"]
                self.assertEqual(env["PGPASSFILE"], "/run/secrets/pgpass")
                self.assertIn("pgpass", service["secrets"])


class Kubernetes(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        cls.text = (ROOT / "deploy/kubernetes/forestmapd.yaml").read_text()
        cls.docs = {d["kind"] + "/" + d["metadata"]["name"]: d
                    for d in yaml.safe_load_all(cls.text)}
        cls.pod = cls.docs["Deployment/forestmapd"]["spec"]["template"]
        cls.container = cls.pod["spec"]["containers"][0]

    def test_tls_secret_metrics_and_network_policy(self):
        volumes = {v["name"]: v for v in self.pod["spec"]["volumes"]}
        self.assertEqual(volumes["tls"]["secret"]["secretName"], "forestmapd-tls")
        mounts = {m["name"]: m["mountPath"] for m in self.container["volumeMounts"]}
        conf = self.docs["ConfigMap/forestmapd-config"]["data"]["forestmapd.conf"]
        self.assertIn(f'tls-cert = "{mounts["tls"]}/tls.crt"', conf)
        self.assertIn(f'tls-key = "{mounts["tls"]}/tls.key"', conf)
        ports = {p["name"]: p["containerPort"] for p in self.container["ports"]}
        annotations = self.pod["metadata"]["annotations"]
        self.assertEqual(annotations["prometheus.io/scrape"], "true")
        self.assertEqual(int(annotations["prometheus.io/port"]), ports["metrics"])
        self.assertIn(f'metrics = "0.0.0.0:{ports["metrics"]}"', conf)
        policy = self.docs["NetworkPolicy/forestmapd"]["spec"]
        self.assertEqual(policy["podSelector"], self.docs["Deployment/forestmapd"]["spec"]["selector"])
        by_port = {p["port"]: rule for rule in policy["ingress"] for p in rule["ports"]}
        self.assertNotIn("from", by_port["grpc"])  # clients from anywhere, with TLS and tokens
        self.assertIn("namespaceSelector", by_port["metrics"]["from"][0])  # Prometheus only
        self.assertEqual(set(policy["policyTypes"]), {"Ingress", "Egress"})
        # Probes on the metrics port (kubelet's gRPC probe speaks no TLS), paths the test serves.
        for probe, path in (("readinessProbe", "/readyz"), ("livenessProbe", "/healthz"),
                            ("startupProbe", "/healthz")):
            self.assertEqual(self.container[probe]["httpGet"], {"path": path, "port": "metrics"})

    def test_config_map_serves_tls_and_the_bootstrap_token_gates_it(self):
        conf = self.docs["ConfigMap/forestmapd-config"]["data"]["forestmapd.conf"]
        bootstrap = re.search(r"exec deploy/forestmapd -- forestmapd (token create .*)$", self.text,
                              re.M).group(1).split()
        with tempfile.TemporaryDirectory() as tmp:
            tmp = pathlib.Path(tmp)
            (tmp / "forestmapd.conf").write_text(conf)
            subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days",
                            "1", "-subj", "/CN=forestmapd", "-addext",
                            "subjectAltName=DNS:localhost,IP:127.0.0.1", "-keyout",
                            str(tmp / "tls.key"), "-out", str(tmp / "tls.crt")],
                           check=True, capture_output=True)
            # The pod's environment: the database from its Secret, the ConfigMap as the file. The
            # test moves what it cannot have (the Secret's mount, ports 50051 and 9464, on the
            # same interfaces) with variables, which win over the file.
            pod = {"FORESTMAPD_CONFIG": str(tmp / "forestmapd.conf"),
                   "FORESTMAPD_DB": str(tmp / "maps.db"),
                   "FORESTMAPD_TLS_CERT": str(tmp / "tls.crt"),
                   "FORESTMAPD_TLS_KEY": str(tmp / "tls.key"),
                   "FORESTMAPD_METRICS": "0.0.0.0:0"}
            token = run([FORESTMAPD] + bootstrap, pod)
            self.assertEqual(token.returncode, 0, token.stderr)
            secret = token.stdout.strip()
            log = open(tmp / "server.log", "w+")
            server = subprocess.Popen([FORESTMAPD], env={**CLEAN_ENV, **pod,
                                                         "FORESTMAPD_LISTEN": "0.0.0.0:0"},
                                      stderr=log)
            try:
                port = self.wait_for(tmp / "server.log", r"serving on [^ ]*:(\d+)")
                metrics = self.wait_for(tmp / "server.log", r"metrics on http://[^ ]*:(\d+)/")
                for path in ("/healthz", "/readyz"):  # the probes' paths
                    with urllib.request.urlopen(f"http://127.0.0.1:{metrics}{path}") as answer:
                        self.assertEqual(answer.status, 200, path)
                lines = [json.loads(line) for line in (tmp / "server.log").read_text().splitlines()]
                # One warning only, the one the ConfigMap explains: plain-HTTP metrics (kept to
                # the namespace monitoring by the NetworkPolicy); none for gRPC, TLS and tokens.
                warnings = [l["msg"] for l in lines if "WARNING" in l["msg"]]
                self.assertEqual(len(warnings), 1, lines)
                self.assertTrue(warnings[0].startswith("WARNING: metrics port listening beyond "
                                                       "loopback WITHOUT TLS"), warnings)
                self.assertIn("warns at start", conf)
                client = [FORESTMAP, "--server", f"localhost:{port}", "--tls-ca",
                          str(tmp / "tls.crt")]
                self.assertEqual(run(client + ["health"], {}).returncode, 0)
                refused = run(client + ["map", "list"], {})
                self.assertNotEqual(refused.returncode, 0)
                self.assertIn("UNAUTHENTICATED", refused.stderr)
                allowed = run(client + ["map", "list"], {"FORESTMAP_TOKEN": secret})
                self.assertEqual(allowed.returncode, 0, allowed.stderr)
            finally:
                server.send_signal(signal.SIGTERM)
                server.wait(timeout=20)
                log.close()

    def wait_for(self, log, pattern):
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            match = re.search(pattern, log.read_text())
            if match:
                return int(match.group(1))
            time.sleep(0.05)
        self.fail("forestmapd did not start: " + log.read_text())


if __name__ == "__main__":
    unittest.main(argv=sys.argv[:1], verbosity=2)
