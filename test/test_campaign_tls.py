"""``strapdown-sim campaign --scheduler tls://…`` with Dask's TLS security: a ``dask scheduler``
and a ``dask worker`` on loopback that require TLS with certificates signed by a CA made here
(with the ``openssl`` command; skipped without it). The campaign
runs with the CA and a client certificate from the command line; without certificates it is
refused with a message; with a certificate of another CA the scheduler does not let it in.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_campaign import DEFAULT, _free_port, _start, _stop  # noqa: E402

from strapdown_ros.campaign.results import finished_runs  # noqa: E402

BIN = Path(sys.executable).parent
pytestmark = pytest.mark.slow


def _openssl(*args: str, cwd: Path) -> None:
    subprocess.run(["openssl", *args], cwd=cwd, check=True, capture_output=True)


def _make_ca(where: Path, name: str) -> tuple[Path, Path]:
    """A self-signed CA (certificate, key) under ``where``."""
    key, cert = where / f"{name}-ca.key", where / f"{name}-ca.pem"
    _openssl("req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "2", "-subj",
             f"/CN={name} test CA", "-keyout", str(key), "-out", str(cert), cwd=where)  # fmt: skip
    return cert, key


def _make_cert(where: Path, name: str, ca: tuple[Path, Path]) -> tuple[Path, Path]:
    """A certificate for 127.0.0.1 signed by ``ca``: (certificate, key)."""
    key, csr, cert = where / f"{name}.key", where / f"{name}.csr", where / f"{name}.pem"
    ext = where / f"{name}.ext"
    ext.write_text("subjectAltName=IP:127.0.0.1,DNS:localhost\n")
    _openssl("req", "-newkey", "rsa:2048", "-nodes", "-subj", f"/CN={name}", "-keyout",
             str(key), "-out", str(csr), cwd=where)  # fmt: skip
    _openssl("x509", "-req", "-in", str(csr), "-CA", str(ca[0]), "-CAkey", str(ca[1]),
             "-CAcreateserial", "-days", "2", "-extfile", str(ext), "-out", str(cert),
             cwd=where)  # fmt: skip
    return cert, key


def _certificates(where: Path) -> dict[str, Path]:
    """The cluster's CA, a certificate for the scheduler and worker, one for the client, and
    one of another CA."""
    if shutil.which("openssl") is None:
        pytest.skip("the openssl command is not installed (needed to make test certificates)")
    ca = _make_ca(where, "cluster")
    node = _make_cert(where, "node", ca)
    client = _make_cert(where, "client", ca)
    stranger = _make_cert(where, "stranger", _make_ca(where, "other"))
    return {
        "ca": ca[0], "node": node[0], "node_key": node[1], "client": client[0],
        "client_key": client[1], "stranger": stranger[0], "stranger_key": stranger[1],
    }  # fmt: skip


def _campaign(out: Path, *extra: str, timeout: float = 300) -> subprocess.CompletedProcess:
    cmd = [str(BIN / "strapdown-sim"), "campaign", str(DEFAULT), "--runs", "2", "--duration",
           "3", "--out", str(out), *extra]  # fmt: skip
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)


def test_campaign_on_a_tls_scheduler(tmp_path):
    certs = _certificates(tmp_path)
    port = _free_port()
    address = f"tls://127.0.0.1:{port}"
    tls = ["--tls-ca-file", str(certs["ca"]), "--tls-cert", str(certs["node"]), "--tls-key",
           str(certs["node_key"])]  # fmt: skip
    dask = str(BIN / "dask")
    procs = [_start([dask, "scheduler", "--host", "127.0.0.1", "--port", str(port),
                     "--protocol", "tls", "--no-dashboard", *tls],
                    tmp_path / "scheduler.log")]  # fmt: skip
    try:
        procs.append(_start([dask, "worker", address, "--nworkers", "1", "--nthreads", "1",
                             "--no-dashboard", *tls], tmp_path / "worker.log"))  # fmt: skip
        deadline = time.monotonic() + 60
        while "Starting established connection" not in (tmp_path / "worker.log").read_text():
            assert time.monotonic() < deadline, (tmp_path / "worker.log").read_text()
            time.sleep(0.2)
        # without certificates: refused at once, with what to give
        plain = _campaign(tmp_path / "plain", "--scheduler", address)
        assert plain.returncode == 2, plain.stderr
        assert "a tls:// scheduler needs certificates" in plain.stderr, plain.stderr
        assert "Traceback" not in plain.stderr
        # certificates for a plain address: refused too
        tcp = _campaign(tmp_path / "tcp", "--scheduler", f"tcp://127.0.0.1:{port}",
                        "--tls-ca-file", str(certs["ca"]), "--tls-cert", str(certs["client"]),
                        "--tls-key", str(certs["client_key"]))  # fmt: skip
        assert tcp.returncode == 2 and "must be tls://" in tcp.stderr, tcp.stderr
        # the client's certificate, signed by the cluster's CA: the runs are computed
        out = tmp_path / "campaign"
        ok = _campaign(out, "--scheduler", address, "--tls-ca-file", str(certs["ca"]),
                       "--tls-cert", str(certs["client"]), "--tls-key", str(certs["client_key"]))
        assert ok.returncode == 0, ok.stdout + ok.stderr
        assert finished_runs(out) == {0, 1}
        assert json.loads((out / "campaign.json").read_text())["runs"] == 2
        # a certificate of another CA: the scheduler does not let the client in
        bad = _campaign(tmp_path / "bad", "--scheduler", address, "--tls-ca-file",
                        str(certs["ca"]), "--tls-cert", str(certs["stranger"]), "--tls-key",
                        str(certs["stranger_key"]))  # fmt: skip
        assert bad.returncode != 0 and not finished_runs(tmp_path / "bad"), bad.stderr
    finally:
        _stop(procs)
