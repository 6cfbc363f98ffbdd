"""Table families on Dask: validation, resume, identity with the serial path, interpolation."""

from __future__ import annotations

import dataclasses
import json
import os
from pathlib import Path

import numpy as np
import pytest

from gms_comp.app.cli import main
from gms_comp.app.scaleout import dask_client, run_jobs
from gms_comp.app.sweep import load_family, load_sweep, run_sweep
from gms_comp.config import default_config_path
from gms_comp.errors import ConfigError, TableError
from gms_comp.tables.table import read_table, write_table

LOADS = "[25.0, 50.0]"


def _sweep_file(tmp_path: Path, axes: str, elements: int = 4) -> Path:
    path = tmp_path / "sweep.toml"
    path.write_text(
        f'[sweep]\nbase_config = "{default_config_path()}"\nelements = {elements}\n'
        f"[sweep.axes]\n{axes}\n"
    )
    return path


@pytest.mark.parametrize(
    ("body", "key"),
    [
        ('[sweep]\nelements = 4\n[sweep.axes]\n"stand.nope" = [1.0]\n', "sweep.axes.stand.nope"),
        ('[sweep]\nelements = 0\n[sweep.axes]\n"stand.ball_loads_N" = [1.0]\n', "sweep.elements"),
        ("[sweep]\nelements = 4\n", "sweep.axes"),
        ('[sweep]\ncolour = "red"\n', "sweep.colour"),
        ('[sweep]\n[sweep.axes]\n"ball_loads_N" = [1.0]\n', "sweep.axes.ball_loads_N"),
        ("[sweep\n", ""),
    ],
)
def test_bad_sweep_files_name_the_key(tmp_path: Path, body: str, key: str) -> None:
    path = tmp_path / "bad.toml"
    path.write_text(body)
    with pytest.raises(ConfigError) as info:
        load_sweep(path)
    assert info.value.key == key
    assert str(path) in str(info.value)


def test_grid_is_the_cartesian_product(tmp_path: Path) -> None:
    spec = load_sweep(
        _sweep_file(
            tmp_path,
            f'"stand.ball_loads_N" = {LOADS}\n"bearing.friction_coefficient" = [1e-3, 2e-3, 3e-3]',
        )
    )
    grid = spec.grid()
    assert len(grid) == 6
    assert {(g["stand.ball_loads_N"], g["bearing.friction_coefficient"]) for g in grid} == {
        (load, mu) for load in (25.0, 50.0) for mu in (1e-3, 2e-3, 3e-3)
    }


def test_invalid_point_is_reported_and_the_others_complete(tmp_path: Path) -> None:
    # 3.0 mm < ball radius 3.175 mm: a groove narrower than the ball is refused by the loader
    spec = load_sweep(
        _sweep_file(tmp_path, '"bearing.raceway_radius_m" = [3.0e-3, 3.5e-3, 4.0e-3]')
    )
    manifest = run_sweep(spec, tmp_path / "fam")
    status = [p["status"] for p in manifest["points"]]
    assert status == ["invalid", "ok", "ok"]
    bad = manifest["points"][0]
    assert "raceway_radius_m" in bad["reason"] and "0000.toml" in bad["reason"]
    on_disk = json.loads((tmp_path / "fam" / "manifest.json").read_text())
    assert on_disk["points"] == manifest["points"]
    for row in manifest["points"][1:]:
        table = read_table(tmp_path / "fam" / row["table"])
        assert table.source_sha256 == row["config_sha256"]
        assert table.n_elements == 4


def test_rerun_resumes_without_recomputing(tmp_path: Path) -> None:
    spec = load_sweep(_sweep_file(tmp_path, f'"stand.ball_loads_N" = {LOADS}'))
    run_sweep(spec, tmp_path / "fam")
    tables = sorted((tmp_path / "fam" / "points").glob("*.json"))
    stamps = [t.stat().st_mtime_ns for t in tables]
    again = run_sweep(spec, tmp_path / "fam")
    assert all(p["status"] == "ok" and p.get("resumed") for p in again["points"])
    assert [t.stat().st_mtime_ns for t in tables] == stamps


def test_family_interpolates_between_loads_and_refuses_outside(tmp_path: Path) -> None:
    spec = load_sweep(_sweep_file(tmp_path, f'"stand.ball_loads_N" = {LOADS}'))
    run_sweep(spec, tmp_path / "fam")
    family = load_family(tmp_path / "fam")
    lo = family.table_at({"stand.ball_loads_N": 25.0}).params
    hi = family.table_at({"stand.ball_loads_N": 50.0}).params
    mid = family.table_at({"stand.ball_loads_N": 37.5}).params
    np.testing.assert_allclose(mid.limit_N, 0.5 * (lo.limit_N + hi.limit_N), rtol=1e-12)
    np.testing.assert_allclose(
        mid.stiffness_N_per_m, 0.5 * (lo.stiffness_N_per_m + hi.stiffness_N_per_m)
    )
    # more load, more friction: the total element limit grows with the preload
    assert hi.limit_N.sum() > lo.limit_N.sum()
    with pytest.raises(TableError, match="outside"):
        family.table_at({"stand.ball_loads_N": 80.0})
    # a point whose elements follow another law is not blended with its neighbour
    point = sorted((tmp_path / "fam" / "points").glob("*.json"))[0]
    table = read_table(point)
    law = dataclasses.replace(table.params, limit_follows_level=True)
    write_table(point, dataclasses.replace(table, params=law))
    with pytest.raises(TableError, match="law"):
        load_family(tmp_path / "fam").table_at({"stand.ball_loads_N": 37.5})


def test_local_cluster_gives_the_serial_result(tmp_path: Path) -> None:
    spec = load_sweep(_sweep_file(tmp_path, f'"stand.ball_loads_N" = {LOADS}'))
    serial = run_sweep(spec, tmp_path / "serial")
    with dask_client(n_workers=2) as client:
        parallel = run_sweep(spec, tmp_path / "dask", client=client)
    for a, b in zip(serial["points"], parallel["points"], strict=True):
        assert a["config_sha256"] == b["config_sha256"]
        assert a["fidelity"] == b["fidelity"]
        ta, tb = (
            read_table(tmp_path / "serial" / a["table"]),
            read_table(tmp_path / "dask" / b["table"]),
        )
        np.testing.assert_array_equal(ta.params.stiffness_N_per_m, tb.params.stiffness_N_per_m)
        np.testing.assert_array_equal(ta.params.limit_N, tb.params.limit_N)


def _dies_once(marker: str) -> int:
    """Kill the worker process the first time it runs; succeed when rescheduled."""
    if not os.path.exists(marker):
        Path(marker).write_text("died")
        os._exit(1)
    return 7


def test_jobs_survive_a_dying_worker(tmp_path: Path) -> None:
    marker = str(tmp_path / "marker")
    with dask_client(n_workers=2) as client:
        results = list(run_jobs(_dies_once, [marker], client=client))
    assert [(r.ok, r.value) for r in results] == [(True, 7)]


def test_sweep_command_writes_a_manifest(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _sweep_file(tmp_path, '"bearing.raceway_radius_m" = [3.0e-3, 3.5e-3]')
    code = main(["sweep", str(path), "--serial", "-o", str(tmp_path / "fam"), "--json"])
    manifest = json.loads(capsys.readouterr().out)
    assert code == 1  # one point is invalid: the run says so
    assert [p["status"] for p in manifest["points"]] == ["invalid", "ok"]


def test_grid_over_the_cap_is_refused_before_it_is_built(tmp_path: Path) -> None:
    values = ", ".join(f"{1e-3 + i * 1e-7:.7g}" for i in range(2000))
    axes = "\n".join(
        f'"{key}" = [{values}]'
        for key in (
            "bearing.friction_coefficient",
            "stand.carriage_velocity_m_s",
            "stand.rolling_distance_per_travel",
        )
    )
    with pytest.raises(ConfigError) as info:
        load_sweep(_sweep_file(tmp_path, axes))
    assert info.value.key == "sweep.axes"
    assert "8e+09 points, more than the 10000" in str(info.value)


def test_a_sweep_file_may_not_name_a_scheduler(tmp_path: Path) -> None:
    """A [scaleout] section in a sweep file (a scheduler, TLS files) is refused: the file
    says what to compute, never where (tests/test_scaleout_security.py: without connecting)."""
    path = _sweep_file(tmp_path, f'"stand.ball_loads_N" = {LOADS}')
    for section in ('scheduler = "tls://10.1.2.3:8786"', 'tls_ca_file = "ca.pem"'):
        path.write_text(_sweep_file(tmp_path, f'"stand.ball_loads_N" = {LOADS}').read_text()
                        + f"\n[scaleout]\n{section}\n")  # fmt: skip
        with pytest.raises(ConfigError) as info:
            load_sweep(path)
        assert info.value.key == "scaleout"
        assert "--scheduler" in str(info.value)


def test_cluster_config_resolves_tls_files_beside_it(tmp_path: Path) -> None:
    """--cluster-config: the user's own config's [scaleout] gives the scheduler and the TLS
    files (relative to that config); the command line's --scheduler wins."""
    from argparse import Namespace

    from gms_comp.app.scaleout import cli_cluster

    (tmp_path / "certs").mkdir()
    for name in ("ca.pem", "me.pem", "me.key"):
        (tmp_path / "certs" / name).write_text("-")
    own = tmp_path / "mine.toml"
    own.write_text(
        '[scaleout]\nscheduler = "tls://10.1.2.3:8786"\ntls_ca_file = "certs/ca.pem"\n'
        'tls_cert = "certs/me.pem"\ntls_key = "certs/me.key"\n'
    )
    args = Namespace(scheduler=None, cluster_config=own, tls_ca_file=None, tls_cert=None,
                     tls_key=None)  # fmt: skip
    scheduler, tls = cli_cluster(args)
    assert scheduler == "tls://10.1.2.3:8786"
    assert tls is not None and tls.key == (tmp_path / "certs" / "me.key").resolve()
    args.scheduler = "tls://10.9.9.9:8786"
    assert cli_cluster(args)[0] == "tls://10.9.9.9:8786"
    own.write_text(own.read_text().replace("me.key", "gone.key"))
    with pytest.raises(ConfigError) as info:
        cli_cluster(args)
    assert info.value.key == "scaleout.tls_key"


def test_two_sweeps_into_one_folder_do_not_race(tmp_path: Path) -> None:
    """Both runs write the same manifest and point files at once: with unique temporary
    names neither fails, and what is left is complete and readable."""
    import threading

    spec = load_sweep(_sweep_file(tmp_path, '"stand.ball_loads_N" = [40.0]', elements=2))
    errors: list[BaseException] = []

    def run() -> None:
        try:
            run_sweep(spec, tmp_path / "fam")
        except BaseException as err:  # collected for the assertion
            errors.append(err)

    threads = [threading.Thread(target=run) for _ in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    manifest = json.loads((tmp_path / "fam" / "manifest.json").read_text())
    assert [p["status"] for p in manifest["points"]] == ["ok"]
    assert read_table(tmp_path / "fam" / "points" / "0000.json").n_elements == 2
    leftovers = [p.name for p in (tmp_path / "fam").rglob("*.tmp*")]
    assert leftovers == []
