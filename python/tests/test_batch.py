"""meshpde.batch: one operation over many mesh files on a dask.distributed cluster.

Every run here is a LocalCluster of worker processes on this machine, as on a laptop;
a cluster differs only in the scheduler's address.
"""
import json
import os
import pathlib
import re
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

import meshpde
import meshpde.batch as batch


@pytest.fixture(scope="module", autouse=True)
def distributed():
    """dask.distributed is Debian's python3-distributed: a failure under CI=true, else a skip."""
    try:
        import distributed as d
    except ImportError:
        if os.environ.get("CI") == "true":
            pytest.fail("python3-distributed is not installed (./scripts/install-deps installs it)")
        pytest.skip("python3-distributed not installed")
    return d


def cohort(folder, count=20):
    """count generated meshes of different sizes and shapes, in three formats."""
    folder.mkdir(exist_ok=True)
    paths = []
    for k in range(count):
        if k % 3 == 0:
            V, F = meshpde.generate.icosphere(2 + k % 2, radius=1.0 + 0.05 * k)
        elif k % 3 == 1:
            V, F = meshpde.generate.tube(radius=1.0 + 0.03 * k, length=6.0, rings=12 + k, segments=16)
        else:
            V, F = meshpde.generate.plane(nx=10 + k, ny=12, size=2.0)
            V[:, 2] = 0.1 * np.sin(3 * V[:, 0]) * np.cos(2 * V[:, 1])
        p = folder / f"mesh{k:02d}{['.off', '.ply', '.obj'][k % 3]}"
        meshpde.write_mesh(p, V, F)
        paths.append(p)
    return paths


FAIR = {"fixed": "halfspace:0,1,0:0.2", "order": 2}


def serial(operation, paths, out, options):
    out.mkdir(exist_ok=True)
    return [batch.process(operation, p, out, options) for p in paths]


def same_files(a, b):
    return a.read_bytes() == b.read_bytes()


def test_two_workers_give_the_outputs_of_a_serial_loop_bit_for_bit(tmp_path):
    paths = cohort(tmp_path / "in")
    for operation, options in [("fair", FAIR), ("curvature", {})]:
        rows = serial(operation, paths, tmp_path / f"serial-{operation}", options)
        table = batch.run(operation, paths, tmp_path / f"dask-{operation}", options=options, workers=2)
        assert len(table) == 20 and len(table.ok) == 20, table.summary()
        assert len({r["worker"] for r in table}) == 2, "both workers should have taken files"
        for row, mine in zip(table, rows):
            assert row["input"] == mine["input"]
            assert row["output"] is not None and mine["output"] is not None
            assert same_files(tmp_path / f"dask-{operation}" / os.path.basename(row["output"]),
                              tmp_path / f"serial-{operation}" / os.path.basename(mine["output"])), row["input"]
            assert row["report"] == mine["report"]
    # The outputs are the operation's: fair moved the free vertices, curvature is a field.
    V0, F0, _ = meshpde.read_mesh(paths[0])
    V1, F1, _ = meshpde.read_mesh(tmp_path / "dask-fair" / "mesh00.off")
    assert np.array_equal(F0, F1) and np.abs(V1 - V0).max() > 1e-3
    V2, _, fields = meshpde.read_mesh(tmp_path / "dask-curvature" / "mesh00.ply")  # .off holds no fields
    H = fields["mean_curvature"]
    assert abs(np.median(H) - 1.0) < 0.02 and np.abs(H - 1.0).max() < 0.2, "a unit sphere's mean curvature is 1"


def test_the_table_is_written_as_json_and_csv_and_each_file_has_its_report(tmp_path):
    paths = cohort(tmp_path / "in", 4)
    table = batch.run("fair", paths, tmp_path / "out", options=FAIR, progress=False)
    written = json.loads((tmp_path / "out" / "batch.json").read_text())
    assert [r["input"] for r in written] == [str(p) for p in paths]
    lines = (tmp_path / "out" / "batch.csv").read_text().splitlines()
    assert lines[0].startswith("input,status,output,seconds,worker,error") and "report.cg_iterations" in lines[0]
    assert len(lines) == 5
    for row in table:
        report = json.loads(open(row["report_file"]).read())
        assert report["status"] == "ok" and report["operation"] == "fair" and report["options"] == FAIR
        assert report["report"]["laplacian"] in ("cotan", "intrinsic")


def test_a_malformed_or_missing_file_is_a_failed_row_and_the_others_complete(tmp_path):
    paths = cohort(tmp_path / "in", 6)
    bad = tmp_path / "in" / "truncated.off"
    bad.write_text("OFF\n4 2 0\n0 0 0\n1 0 0\n0 1 0\n")
    missing = tmp_path / "in" / "absent.ply"
    folder = tmp_path / "in" / "folder.ply"  # a folder, and a file of another kind: rows of their own
    folder.mkdir()
    notes = tmp_path / "in" / "notes.txt"
    notes.write_text("not a mesh")
    table = batch.run("fair", paths[:3] + [bad, missing, folder, notes] + paths[3:], tmp_path / "out", options=FAIR)
    assert len(table.ok) == 6 and len(table.failed) == 4
    assert "truncated.off" in table[3]["error"] and "InputError" in table[3]["error"]
    assert "absent.ply" in table[4]["error"]
    assert "folder.ply: is a directory" in table[5]["error"]
    assert "notes.txt" in table[6]["error"] and "InputError" in table[6]["error"]
    assert json.loads((tmp_path / "out" / "truncated.json").read_text())["status"] == "failed"
    assert not list((tmp_path / "out").glob("truncated.off*")), "no output for a failed file"
    assert not list((tmp_path / "out").glob(".*.tmp")), "no temporary file left behind"


def test_a_file_that_kills_its_worker_is_a_failed_row_and_the_others_complete(tmp_path):
    paths = cohort(tmp_path / "in", 6)

    def crash_on_mesh03(V, F, **options):  # pickled by value: the workers need not import this file
        import os as os_
        import signal as signal_
        if len(V) == len(meshpde.read_mesh(options.pop("victim"))[0]):
            os_.kill(os_.getpid(), signal_.SIGKILL)  # as a segfault in a native library would
        return meshpde.fair(V, F, **options)

    table = batch.run(crash_on_mesh03, paths, tmp_path / "out", options=dict(FAIR, victim=str(paths[3])))
    assert [r["status"] for r in table] == ["ok"] * 3 + ["failed"] + ["ok"] * 2
    assert "KilledWorker" in table[3]["error"], table[3]["error"]


def test_killing_a_worker_mid_run_still_completes_the_batch(tmp_path, distributed):
    paths = cohort(tmp_path / "in")
    serial_rows = serial("fair", paths, tmp_path / "serial", FAIR)

    def slow_fair(V, F, **options):  # long enough that the kill lands while files are running
        import time as time_
        time_.sleep(0.25)
        return meshpde.fair(V, F, **options)

    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster, distributed.Client(cluster) as client:
        pids = client.run(os.getpid)
        result = {}
        runner = threading.Thread(target=lambda: result.update(
            table=batch.run(slow_fair, paths, tmp_path / "out", options=FAIR, client=client)))
        runner.start()
        victim, deadline = None, time.time() + 60
        while victim is None and time.time() < deadline:  # a worker running a file, once two are done
            busy = {w: keys for w, keys in client.processing().items() if keys}
            if busy and len(list((tmp_path / "out").glob("*.json"))) >= 2:
                victim, running = next(iter(busy.items()))
            time.sleep(0.02)
        assert victim is not None, "no worker was seen running a file"
        os.kill(pids[victim], signal.SIGKILL)
        # the files it held (keys meshpde-batch-NAME-HEX)
        lost = {key.split("-", 2)[2].rsplit("-", 1)[0] for key in running}
        runner.join(timeout=240)
        assert not runner.is_alive(), "the batch did not finish after a worker was killed"
    table = result["table"]
    assert len(table.ok) == 20, table.summary()
    assert lost, "the killed worker held no file"
    # The files the killed worker held were run again by another. (One it finished in
    # the moment between the snapshot of its tasks and the kill keeps its row: so at
    # least one, not every one, must have moved.)
    moved = [row for row in table if os.path.basename(row["input"]) in lost and row["worker"] != victim]
    assert moved, f"none of the killed worker's files {sorted(lost)} was run again by another worker"
    for row, mine in zip(table, serial_rows):
        assert same_files(tmp_path / "out" / os.path.basename(row["output"]),
                          tmp_path / "serial" / os.path.basename(mine["output"])), row["input"]


def test_a_rerun_skips_the_files_done_and_redoes_what_changed(tmp_path):
    paths = cohort(tmp_path / "in", 5)
    bad = tmp_path / "in" / "bad.off"
    bad.write_text("OFF\n3 1 0\n0 0 0\n")
    first = batch.run("fair", paths + [bad], tmp_path / "out", options=FAIR)
    assert len(first.ok) == 5 and len(first.failed) == 1
    again = batch.run("fair", paths + [bad], tmp_path / "out", options=FAIR)
    assert len(again.skipped) == 5 and len(again.failed) == 1, again.summary()   # a failure is retried
    assert [r["output"] for r in again.skipped] == [r["output"] for r in first.ok]
    os.utime(paths[2], ns=(time.time_ns(), time.time_ns() + 10**9))              # an input changed
    os.unlink(first[4]["output"])                                                # an output was deleted
    third = batch.run("fair", paths, tmp_path / "out", options=FAIR)
    assert [r["status"] for r in third] == ["skipped", "skipped", "ok", "skipped", "ok"]
    other = batch.run("fair", paths, tmp_path / "out", options=dict(FAIR, order=1))  # other settings
    assert len(other.ok) == 5
    assert len(batch.run("fair", paths, tmp_path / "out", options=dict(FAIR, order=1), resume=False).ok) == 5


def test_per_file_options_come_from_a_callable(tmp_path):
    paths = [p for p in cohort(tmp_path / "in", 6) if p.suffix == ".ply"]  # the tubes
    handles = {p.name: 5 + k for k, p in enumerate(paths)}
    table = batch.run("correct", paths, tmp_path / "out",
                      options=lambda p: {"vertices": [handles[p.name]], "moves": [(0.2, 0.0, 0.0)], "radius": 1.5})
    assert len(table.ok) == 2
    for p, row in zip(paths, table):
        V0, _, _ = meshpde.read_mesh(p)
        V1, _, fields = meshpde.read_mesh(row["output"])
        moved = np.linalg.norm(V1 - V0, axis=1)
        assert np.argmax(moved) == handles[p.name] and abs(moved.max() - 0.2) < 1e-9
        assert np.allclose(fields["displacement"], V1 - V0, atol=1e-9)
        assert row["report"]["handles"] == 1 and row["report"]["moved_vertices"] > 1


def test_bad_arguments_are_refused_before_any_work(tmp_path):
    a, b = tmp_path / "x" / "m.off", tmp_path / "y" / "m.ply"
    with pytest.raises(meshpde.InputError, match="would both write"):
        batch.run("fair", [a, b], tmp_path / "out", options=FAIR)
    with pytest.raises(meshpde.InputError, match="unknown operation 'smoothen'"):
        batch.run("smoothen", [a], tmp_path / "out")
    assert not (tmp_path / "out").exists()


def test_the_command_line_runs_a_batch_and_exits_non_zero_on_a_failure(tmp_path):
    paths = cohort(tmp_path / "in", 3)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    cmd = [sys.executable, "-m", "meshpde.batch", "fair", str(tmp_path / "out"), *map(str, paths),
           "--options", json.dumps(FAIR), "--format", ".vtp" if meshpde.has_medical else ".ply", "--pictures"]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env)
    assert done.returncode == 0, done.stderr
    assert "3 files: 3 ok, 0 failed, 0 skipped" in done.stderr
    for p in paths:
        assert (tmp_path / "out" / (p.stem + (".vtp" if meshpde.has_medical else ".ply"))).exists()
        png = (tmp_path / "out" / (p.stem + ".png")).read_bytes()
        assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 2000
    assert "picture" in (tmp_path / "out" / "batch.csv").read_text().splitlines()[0]
    again = subprocess.run(cmd + [str(tmp_path / "in" / "missing.off")], capture_output=True, text=True,
                           timeout=300, env=env)
    assert again.returncode == 1 and "4 files: 0 ok, 1 failed, 3 skipped" in again.stderr, again.stderr
    bad = subprocess.run(cmd + ["--options", "[1]"], capture_output=True, text=True, timeout=60, env=env)
    assert bad.returncode == 2 and "--options: expected a JSON object" in bad.stderr


def test_the_same_command_runs_on_a_cluster_given_the_schedulers_address(tmp_path):
    """A dask-scheduler and a dask-worker of two processes, as on a cluster's nodes
    (here on loopback), and the command given --scheduler ADDRESS."""
    paths = cohort(tmp_path / "in", 6)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    info = tmp_path / "scheduler.json"
    elsewhere = tmp_path / "node"
    elsewhere.mkdir()
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                               "--port", "0", "--no-dashboard", "--scheduler-file", str(info)],
                              env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.time() + 60
        while not info.exists() and time.time() < deadline:
            time.sleep(0.1)
        assert info.exists(), "the scheduler did not start"
        procs.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file",
                                       str(info), "--nworkers", "2", "--nthreads", "1", "--no-dashboard"],
                                      env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                                      cwd=elsewhere))  # not the caller's working directory
        address = json.loads(info.read_text())["address"]
        from distributed import Client
        with Client(address, timeout=60) as client:
            client.wait_for_workers(2, timeout=60)
        out = tmp_path / "out"
        done = subprocess.run([sys.executable, "-m", "meshpde.batch", "fair", "out", *[os.path.relpath(p, tmp_path)
                               for p in paths], "--options", json.dumps(FAIR), "--scheduler", address],
                              capture_output=True, text=True, timeout=300, env=env, cwd=tmp_path)
        assert done.returncode == 0, done.stderr
        assert f"scheduler {address}, 2 workers" in done.stderr
        table = json.loads((out / "batch.json").read_text())
        assert [r["status"] for r in table] == ["ok"] * 6
        rows = serial("fair", paths, tmp_path / "serial", FAIR)
        for row, mine in zip(table, rows):
            assert same_files(pathlib.Path(row["output"]), pathlib.Path(mine["output"])), row["input"]
    finally:
        for p in reversed(procs):
            p.terminate()
        for p in procs:
            try:
                p.wait(timeout=30)
            except subprocess.TimeoutExpired:
                p.kill()


def test_the_snippets_of_docs_batch_md_run(tmp_path, monkeypatch, capsys):
    if not meshpde.has_medical:
        pytest.skip("docs/batch.md reads .vtp files: build with the medical component")
    doc = pathlib.Path(__file__).parents[2] / "docs" / "batch.md"
    snippets = re.findall(r"```python\n(.*?)```", doc.read_text(encoding="utf-8"), flags=re.S)
    assert len(snippets) == 2
    monkeypatch.chdir(tmp_path)
    (tmp_path / "cohort").mkdir()
    for k in range(3):  # vessel-sized tubes, open at both ends
        V, F = meshpde.generate.tube(radius=4.0 + k, length=40.0, rings=30, segments=24)
        meshpde.write_mesh(tmp_path / "cohort" / f"case{k + 1:03d}.vtp", V, F)
    namespace = {"__name__": "__main__"}
    for k, code in enumerate(snippets):
        exec(compile(code, f"docs/batch.md snippet {k + 1}", "exec"), namespace)
    printed = capsys.readouterr().out.splitlines()
    assert printed[0] == "3 files: 3 ok, 0 failed, 0 skipped"
    assert [round(d, 9) for d in json.loads(printed[1])] == [1.5, 0.8, 1.0]
    assert len(list((tmp_path / "faired").glob("case*.vtp"))) == 3
