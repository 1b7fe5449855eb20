"""API keys and mutual TLS through the client, against a server configured as
tests/security_e2e_test.cc configures one (certificates from tests/make_test_certificates.sh)."""

import os
import subprocess

import pytest

import shapeid
from conftest import ServerProcess, sha256, shape

READ = "shapeid_py_read_5f0c9a1e7b2d4c3f8a6e"
WRITE = "shapeid_py_write_91d2b7c4e8f3a6d0c5b1"
ADMIN = "shapeid_py_admin_3c7e1a9f5b2d8e4c6a0f"
CLOUD = shape(0, 3)


@pytest.fixture(scope="module")
def certificates(tmp_path_factory):
    directory = tmp_path_factory.mktemp("certs")
    script = os.path.join(os.environ["SHAPEID_SOURCE_DIR"], "tests", "make_test_certificates.sh")
    subprocess.run(["sh", script, str(directory)], check=True)
    return directory


@pytest.fixture(scope="module")
def secure_server(certificates):
    keys = "robot read %s;trainer write %s;ops admin %s" % (sha256(READ), sha256(WRITE),
                                                           sha256(ADMIN))
    process = ServerProcess("--api_keys=" + keys,
                            "--tls_cert=%s" % (certificates / "server.pem"),
                            "--tls_key=%s" % (certificates / "server.key"),
                            "--tls_client_ca=%s" % (certificates / "ca.pem"))
    yield process
    assert process.stop() == 0
    log = process.stderr_text()
    assert "3 API keys (1 read, 1 write, 1 admin)" in log
    for key in (READ, WRITE, ADMIN):
        assert key not in log


def connect(server, certificates, key=None, client_certificate=True, **kwargs):
    files = {"tls_ca_file": certificates / "ca.pem"}
    if client_certificate:
        files.update(tls_cert_file=certificates / "client.pem",
                     tls_key_file=certificates / "client.key")
    return shapeid.Client(server.address, api_key=key, **files, **kwargs)


def test_scopes_over_mutual_tls(secure_server, certificates):
    with connect(secure_server, certificates) as anonymous:
        assert anonymous.health().serving  # health needs no key
        with pytest.raises(shapeid.UnauthenticatedError, match="missing API key"):
            anonymous.list_galleries()
    with connect(secure_server, certificates, "shapeid_py_wrong_000000000000000000") as wrong:
        with pytest.raises(shapeid.UnauthenticatedError, match="unknown API key"):
            wrong.list_galleries()
    with connect(secure_server, certificates, READ) as robot, \
            connect(secure_server, certificates, WRITE) as trainer, \
            connect(secure_server, certificates, ADMIN) as ops:
        with pytest.raises(shapeid.PermissionDeniedError, match="key 'robot' lacks scope write"):
            robot.create_gallery("parts")
        trainer.create_gallery("parts")
        trainer.train("parts", [CLOUD, shape(2, 4)], ["plate", "rod"])
        assert robot.classify("parts", shape(0, 5)).label == "plate"
        with pytest.raises(shapeid.PermissionDeniedError, match="lacks scope admin"):
            trainer.delete_gallery("parts")
        assert ops.delete_gallery("parts") == 2


def test_tls_failures_are_unavailable(secure_server, certificates):
    # No client certificate: the server's handshake refuses it.
    with connect(secure_server, certificates, ADMIN, client_certificate=False) as c:
        with pytest.raises(shapeid.UnavailableError):
            c.list_galleries(timeout=5)
    # Plaintext to a TLS server.
    with shapeid.Client(secure_server.address, api_key=ADMIN) as c:
        with pytest.raises(shapeid.UnavailableError):
            c.list_galleries(timeout=5)
    # A certificate for another name.
    with connect(secure_server, certificates, ADMIN, tls_server_name="elsewhere.example") as c:
        with pytest.raises(shapeid.UnavailableError):
            c.list_galleries(timeout=5)
    # The name the certificate does carry, asked for explicitly.
    with connect(secure_server, certificates, ADMIN, tls_server_name="localhost") as c:
        assert c.list_galleries() == []


def test_keys_over_plaintext_loopback():
    process = ServerProcess("--api_keys=robot read %s" % sha256(READ))
    try:
        with shapeid.Client(process.address, api_key=READ) as robot:
            assert robot.list_galleries() == []
            with pytest.raises(shapeid.PermissionDeniedError):
                robot.create_gallery("g")
    finally:
        assert process.stop() == 0
