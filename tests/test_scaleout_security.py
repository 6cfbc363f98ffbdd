"""Dask is not open to the network: a loopback-only local cluster, TLS to a remote one.

The TLS test makes its own certificate authority, starts a TLS-only scheduler and
worker on 127.0.0.1 and runs a one-point sweep through ``gms-comp sweep --scheduler
tls://...``; a client without the certificates, or with ones from another authority,
is refused in one line.
"""

from __future__ import annotations

import argparse
import datetime
import ipaddress
import json
import select
import socket
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from gms_comp.app.cli import main
from gms_comp.app.scaleout import PLAIN_TCP_WARNING, _check_remote, dask_client, tls_files
from gms_comp.arguments import scheduler_address
from gms_comp.config import default_config_path
from gms_comp.errors import InputError

crypto = pytest.importorskip(
    "cryptography", reason="the TLS test makes its certificates with the cryptography package"
)


def _loopback(address: str) -> bool:
    return ipaddress.ip_address(urlsplit(address).hostname or "").is_loopback


@pytest.mark.slow
def test_local_cluster_listens_on_loopback_only() -> None:
    with dask_client(n_workers=1) as client:
        assert _loopback(client.scheduler.address), client.scheduler.address
        workers = client.scheduler_info()["workers"]
        assert workers and all(_loopback(w) for w in workers), list(workers)


@pytest.mark.parametrize(
    "value",
    ["not a url", "http://host:8786", "tcp://", "tcp://host:99999", "tls://a b:1", "host:8786"],
)
def test_bad_scheduler_addresses_are_refused(value: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        scheduler_address(value)


@pytest.mark.parametrize(
    "value", ["tcp://10.0.0.5:8786", "tls://sched.example:8786", "tls://[::1]:1"]
)
def test_scheduler_addresses_are_accepted(value: str) -> None:
    assert scheduler_address(value) == value


def test_plain_tcp_is_refused_unless_the_user_says_insecure(
    capsys: pytest.CaptureFixture[str],
) -> None:
    for address in ("tcp://192.0.2.7:8786", "tcp://127.0.0.1:8786"):
        with pytest.raises(InputError, match="--insecure-scheduler"):
            _check_remote(address, None)
    assert capsys.readouterr().err == ""
    _check_remote("tcp://192.0.2.7:8786", None, insecure=True)
    err = capsys.readouterr().err
    assert err == PLAIN_TCP_WARNING.format(address="tcp://192.0.2.7:8786") + "\n"
    assert "runs any code" in err


def test_a_sweep_file_scheduler_is_refused_without_connecting(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A hostile sweep file's scheduler is never contacted: a listening socket at its
    address sees no connection, whatever the flags; the refusal is one line, exit 2."""
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        port = server.getsockname()[1]
        sweep = tmp_path / "hostile.toml"
        sweep.write_text(
            f'[sweep]\nbase_config = "{default_config_path()}"\nelements = 2\n'
            '[sweep.axes]\n"stand.ball_loads_N" = [50.0]\n'
            f'[scaleout]\nscheduler = "tcp://127.0.0.1:{port}"\n'
        )
        for extra in ([], ["--insecure-scheduler"], ["--workers", "1"]):
            assert main(["sweep", str(sweep), *extra, "-o", str(tmp_path / "fam")]) == 2
            err = capsys.readouterr().err.strip().splitlines()
            assert len(err) == 1 and "scaleout" in err[0] and "--scheduler" in err[0], err
        readable, _, _ = select.select([server], [], [], 0.5)
        assert not readable, "the sweep file's scheduler was contacted"
    assert not (tmp_path / "fam").exists()


def test_transport_and_tls_files_must_match(tmp_path: Path) -> None:
    pem = tmp_path / "x.pem"
    pem.write_text("-")
    files = tls_files(pem, pem, pem)
    with pytest.raises(InputError, match="needs --tls-ca-file"):
        _check_remote("tls://192.0.2.7:8786", None)
    with pytest.raises(InputError, match="plain tcp; use tls://"):
        _check_remote("tcp://192.0.2.7:8786", files)
    with pytest.raises(InputError, match="give all three"):
        tls_files(pem, None, pem)
    with pytest.raises(InputError, match="is not a file"):
        tls_files(pem, pem, tmp_path / "missing.pem")


# --- a real TLS scheduler --------------------------------------------------------------


def _write_authority(folder: Path, name: str) -> dict[str, Path]:
    """A self-signed CA and one certificate for 127.0.0.1 signed by it (PEM files)."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.UTC)

    def build(
        subject: str,
        issuer: x509.Name | None,
        issuer_key: ec.EllipticCurvePrivateKey | None,
        ca: bool,
    ) -> tuple[ec.EllipticCurvePrivateKey, x509.Certificate]:
        key = ec.generate_private_key(ec.SECP256R1())
        subject_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, subject)])
        builder = (
            x509.CertificateBuilder()
            .subject_name(subject_name)
            .issuer_name(issuer or subject_name)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(x509.BasicConstraints(ca=ca, path_length=None), critical=True)
        )
        if not ca:
            builder = builder.add_extension(
                x509.SubjectAlternativeName(
                    [x509.IPAddress(ipaddress.ip_address("127.0.0.1")), x509.DNSName("localhost")]
                ),
                critical=False,
            )
        cert = builder.sign(issuer_key or key, hashes.SHA256())
        return key, cert

    ca_key, ca_cert = build(f"{name} CA", None, None, True)
    key, cert = build("127.0.0.1", ca_cert.subject, ca_key, False)
    files = {"ca": folder / f"{name}-ca.pem", "cert": folder / f"{name}-cert.pem"}
    files["key"] = folder / f"{name}-key.pem"
    files["ca"].write_bytes(ca_cert.public_bytes(serialization.Encoding.PEM))
    files["cert"].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
    files["key"].write_bytes(
        key.private_bytes(
            serialization.Encoding.PEM,
            serialization.PrivateFormat.PKCS8,
            serialization.NoEncryption(),
        )
    )
    return files


@pytest.fixture
def tls_cluster(tmp_path: Path) -> Iterator[tuple[str, dict[str, Path]]]:
    from distributed import LocalCluster
    from distributed.security import Security

    files = _write_authority(tmp_path, "good")
    security = Security(
        tls_ca_file=str(files["ca"]),
        tls_scheduler_cert=str(files["cert"]),
        tls_scheduler_key=str(files["key"]),
        tls_worker_cert=str(files["cert"]),
        tls_worker_key=str(files["key"]),
        tls_client_cert=str(files["cert"]),
        tls_client_key=str(files["key"]),
        require_encryption=True,
    )
    with LocalCluster(
        n_workers=1,
        threads_per_worker=1,
        processes=False,
        protocol="tls://",
        host="127.0.0.1",
        security=security,
        dashboard_address=None,
    ) as cluster:
        yield cluster.scheduler_address, files


@pytest.mark.slow
def test_sweep_runs_through_a_tls_scheduler(
    tmp_path: Path,
    tls_cluster: tuple[str, dict[str, Path]],
    capsys: pytest.CaptureFixture[str],
) -> None:
    address, files = tls_cluster
    assert address.startswith("tls://127.0.0.1:")
    sweep = tmp_path / "one.toml"
    sweep.write_text(
        f'[sweep]\nbase_config = "{default_config_path()}"\nelements = 2\n'
        '[sweep.axes]\n"stand.ball_loads_N" = [50.0]\n'
    )
    tls = ["--tls-ca-file", str(files["ca"]), "--tls-cert", str(files["cert"])]
    tls += ["--tls-key", str(files["key"])]
    out = tmp_path / "fam"
    assert main(["sweep", str(sweep), "--scheduler", address, *tls, "-o", str(out)]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    assert [p["status"] for p in manifest["points"]] == ["ok"]
    capsys.readouterr()

    # Plain tcp to the TLS port: refused before connecting, one line, exit 2; said to be
    # insecure, it reaches no scheduler there.
    plain = address.replace("tls://", "tcp://")
    assert main(["sweep", str(sweep), "--scheduler", plain, "-o", str(out)]) == 2
    assert "--insecure-scheduler" in capsys.readouterr().err
    argv = ["sweep", str(sweep), "--scheduler", plain, "--insecure-scheduler", "-o", str(out)]
    assert main(argv) == 2
    assert "cannot reach the Dask scheduler" in capsys.readouterr().err

    # Certificates from another authority: refused the same way.
    other = _write_authority(tmp_path, "other")
    wrong = ["--tls-ca-file", str(other["ca"]), "--tls-cert", str(other["cert"])]
    wrong += ["--tls-key", str(other["key"])]
    assert main(["sweep", str(sweep), "--scheduler", address, *wrong, "-o", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot reach the Dask scheduler" in err[0]
