"""One writer per folder, with two real processes: a second `sweep` on a grid, or a second
`build-data` into a folder, is refused at once naming the holder; a killed holder's lock is free."""

import json
import os
import re
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest

from radar2shape import cli
from radar2shape.errors import UserInputError
from radar2shape.locking import folder_lock, holder_of

from test_preemption import REPO, start, toy_grid  # noqa: E402 - same folder, pytest's rootdir import


def wait_for_lock(path: Path, process: subprocess.Popen, timeout: float = 60) -> dict:
    """The holder record once the process has written it into its lock file."""
    deadline = time.time() + timeout
    while True:
        assert process.poll() is None, process.communicate()
        assert time.time() < deadline, f"no lock {path}"
        try:
            info = json.loads(path.read_text() or "null")
        except (OSError, ValueError):
            info = None
        if info:
            return info
        time.sleep(0.02)


def refusal(folder: Path, what: str, label: str, pid: int) -> re.Pattern:
    lock = {"another sweep": ".sweep.lock"}.get(what, ".build-data.lock")
    return re.compile(
        rf"error: {re.escape(label)}: {re.escape(str(folder))} is in use by {re.escape(what)} \(pid {pid} on host "
        rf"{re.escape(socket.gethostname())}, started \d{{4}}-\d\d-\d\dT[0-9:]+[+-][0-9:]+\); wait for it to end "
        rf"\(its lock goes with it\), or, only if that process is gone and the lock stays, delete "
        rf"{re.escape(str(folder / lock))}$")


def test_a_second_sweep_is_refused_and_report_notes_the_writer(tmp_path, monkeypatch, capsys):
    grid = toy_grid(tmp_path, jobs=1, epochs=500)
    runs = tmp_path / "runs"
    first = start("sweep", grid)
    try:
        holder = wait_for_lock(runs / ".sweep.lock", first)
        assert holder["pid"] == first.pid and holder["host"] == socket.gethostname()
        second = start("sweep", grid)
        _, err = second.communicate(timeout=60)
        assert second.returncode == 2
        assert len(err.splitlines()) == 1 and refusal(runs, "another sweep", "radar2shape sweep", first.pid).match(err.strip()), err

        # report does not wait for the sweep: it says a sweep writes and reports what is finished
        from radar2shape import reporting

        monkeypatch.setattr(reporting, "write_report", lambda *args: tmp_path / "report.md")
        assert cli.run_tool("report", ["--grid", str(grid)]) == 0
        out = capsys.readouterr().out.splitlines()
        assert out[0].startswith(f"note: a sweep is writing {runs} (pid {first.pid} on host {socket.gethostname()}, ")
    finally:
        os.kill(first.pid, signal.SIGKILL)  # a holder that cannot clean up
        first.wait()
    assert (runs / ".sweep.lock").is_file()  # the file stays, its lock went with the process
    assert holder_of(runs, ".sweep.lock") is None
    with folder_lock(runs, ".sweep.lock", "another sweep", "radar2shape sweep") as path:
        assert json.loads(path.read_text())["pid"] == os.getpid()
    assert not path.exists()  # a clean release removes it


def test_a_second_build_data_into_the_same_folder_is_refused(tmp_path):
    out = tmp_path / "data"
    # many shapes: the first build is still running when the second asks (it is killed, not finished)
    args = ["build-data", "--config", REPO / "conf/data/parts_tiny.yaml", "--out", out, "--num", 3000, "--quiet"]
    first = start(*args)
    try:
        wait_for_lock(out / ".build-data.lock", first)
        second = start(*args)
        _, err = second.communicate(timeout=60)
        assert second.returncode == 2
        assert len(err.splitlines()) == 1
        assert refusal(out, "another build-data of shard 0/1", "--out", first.pid).match(err.strip()), err
    finally:
        os.kill(first.pid, signal.SIGKILL)
        first.wait()
    with folder_lock(out, ".build-data.lock", "x", "--out"):  # free again, the stale file notwithstanding
        pass


def test_lock_refusal_in_process_names_the_holder(tmp_path):
    with folder_lock(tmp_path, "x.lock", "a writer", "--out"):
        assert holder_of(tmp_path, "x.lock")["pid"] == os.getpid()
        with pytest.raises(UserInputError, match=rf"in use by a writer \(pid {os.getpid()} on host "):
            with folder_lock(tmp_path, "x.lock", "a writer", "--out"):
                pass
    assert holder_of(tmp_path, "x.lock") is None and not (tmp_path / "x.lock").exists()
