"""Every command that writes checks its output path before any work: one line naming the option, the path and
what is wrong, exit status 2, nothing left behind. The work itself is replaced by a function that fails the
test, so a check that came after it would show."""

import json
import subprocess
import sys

import pytest

from frbench.cli import main
from frbench.io import check_output_path


def _no_work(*args, **kwargs):
    raise AssertionError("work started before the output path was checked")


@pytest.fixture
def blocker(tmp_path):
    """A regular file standing where a folder would have to be."""
    path = tmp_path / "a_file"
    path.write_text("not a folder")
    return path


@pytest.fixture
def results(tmp_path):
    path = tmp_path / "results.json"
    path.write_text("{}")
    return path


def _listing(folder):
    return sorted(p.name for p in folder.rglob("*"))


@pytest.mark.parametrize("argv, patch, message", [
    (["render", "--out", "{blocker}/e.gif"], "frbench.evaluation.grid.validate",
     "frbench render: error: --out {blocker}/e.gif: cannot create it, {blocker} is a file, not a folder"),
    (["render", "--out", "{tmp}/e.avi"], "frbench.evaluation.grid.validate",
     "frbench render: error: --out {tmp}/e.avi: expected a .gif or .mp4 file"),
    (["render", "--out", "{tmp}/e.gif", "--frames", "{blocker}"], "frbench.evaluation.grid.validate",
     "frbench render: error: --frames {blocker}: is a file, expected a folder"),
    (["terrain", "show", "stairs", "--out", "/proc/x.png"], "frbench.terrains.make_terrain",
     "frbench terrain: error: --out /proc/x.png: cannot write in /proc ("),
    (["terrain", "show", "stairs", "--out", "{tmp}"], "frbench.terrains.make_terrain",
     "frbench terrain: error: --out {tmp}: expected a .png file"),
    (["evaluate", "--out", "/proc/r.json"], "frbench.evaluation.grid.validate",
     "frbench evaluate: error: --out /proc/r.json: cannot write in /proc ("),
    (["evaluate", "--out", "{tmp}"], "frbench.evaluation.grid.validate",
     "frbench evaluate: error: --out {tmp}: is a folder, expected a file path"),
    (["export", "--policy", "frnet", "--out", "/proc/frnet.onnx"], "frbench.policies.registry.load_policy",
     "frbench export: error: --out /proc/frnet.onnx: cannot write in /proc ("),
    (["export", "--policy", "frnet", "--out", "{tmp}/frnet.pt"], "frbench.policies.registry.load_policy",
     "frbench export: error: --out {tmp}/frnet.pt: expected a .onnx file"),
    (["plot-results", "{results}", "--out", "{blocker}"], "frbench.analysis.success_plots.load_results",
     "frbench plot-results: error: --out {blocker}: is a file, expected a folder"),
    (["compare", "{results}", "--out", "/proc/tables.md"], "frbench.analysis.success_plots.load_results",
     "frbench compare: error: --out /proc/tables.md: cannot write in /proc ("),
])
def test_a_bad_output_path_fails_before_work_in_one_line(tmp_path, blocker, results, monkeypatch, capsys,
                                                         argv, patch, message):
    fill = {"blocker": blocker, "tmp": tmp_path, "results": results}
    monkeypatch.setattr(patch, _no_work)
    before = _listing(tmp_path)
    assert main([a.format(**fill) for a in argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith(message.format(**fill)) and err.count("\n") == 1, err
    assert _listing(tmp_path) == before and blocker.read_text() == "not a folder"


def test_the_check_creates_nothing_and_accepts_new_folders(tmp_path):
    target = tmp_path / "new" / "deeper" / "r.json"
    assert check_output_path(target) == target
    assert _listing(tmp_path) == []  # neither the folders nor the probe file remain
    assert check_output_path(tmp_path / "plots", folder=True) == tmp_path / "plots"


def test_an_existing_read_only_file_is_refused(tmp_path):
    import os

    if os.geteuid() == 0:
        pytest.skip("root may write read-only files")
    target = tmp_path / "r.json"
    target.write_text("old")
    target.chmod(0o444)
    with pytest.raises(Exception, match="the file exists and is not writable"):
        check_output_path(target)


def test_policies_lists_without_torch_and_describes_each_checkpoint_from_its_config():
    code = ("import sys, json, io, contextlib\n"
            "from frbench.cli import main\n"
            "buffer = io.StringIO()\n"
            "with contextlib.redirect_stdout(buffer):\n"
            "    main(['policies', '--json'])\n"
            "print(json.dumps({'torch': 'torch' in sys.modules, 'rows': json.loads(buffer.getvalue())}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    report = json.loads(done.stdout)
    assert report["torch"] is False
    rows = {row["name"]: row for row in report["rows"]}
    assert rows["frnet"]["method"] == "frnet" and rows["frnet"]["env_steps"] == 15089664
    assert rows["frnet"]["description"].startswith("frnet, 15.09 M env steps, 183 min training, trained on 32 sampled")
    assert rows["rma-adaptation-3m"]["description"].startswith("rma-adaptation, 0.50 M env steps")
    assert "without the stability reward terms" in rows["frnet-no-stability-3m"]["description"]
    checkpoints = [row for row in rows.values() if row["checkpoint"]]
    assert len({row["description"] for row in checkpoints}) == len(checkpoints)
    assert rows["frnet"]["robots"] == ["go2", "go1", "aliengo", "spot_like", "lite3_like"]
    assert rows["scripted-humanoid"]["robots"] == ["g1"]
    assert "pybullet build time" not in done.stdout + done.stderr


def test_importing_pybullet_through_frbench_prints_nothing():
    done = subprocess.run([sys.executable, "-c", "import frbench.backends.pybullet_backend, frbench.backends.terrain_build"],
                          capture_output=True, text=True, check=True)
    assert done.stdout == "" and done.stderr == ""


@pytest.mark.slow
def test_ctrl_c_during_an_evaluation_with_workers_prints_one_line_and_exits_130(tmp_path):
    import os
    import signal
    import time

    out = tmp_path / "r.json"
    # 144 cells: minutes of work on two workers, so that the interrupt comes while cells are running
    argv = [sys.executable, "-m", "frbench.cli", "evaluate", "--policy", "scripted", "--robots", "go2", "--backends",
            "mujoco,pybullet", "--terrains", "flat,rough,stairs", "--levels", "1,5,10", "--seeds", "0,1,2,3,4,5,6,7",
            "--episodes", "8", "--jobs", "2", "--out", str(out)]
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    time.sleep(15)  # the workers have started and are running cells
    os.killpg(process.pid, signal.SIGINT)  # what Ctrl-C does: SIGINT to the whole foreground group
    stdout, stderr = process.communicate(timeout=60)
    lines = [line for line in stderr.decode().replace("\r", "\n").splitlines() if line.strip() and "%|" not in line]
    assert process.returncode == 130
    assert lines[-1] == "frbench evaluate: interrupted" and len(lines) == 2, lines  # the header, then that line
    assert "Traceback" not in stderr.decode() and not out.exists()


def test_a_closed_stdout_pipe_ends_the_command_quietly(monkeypatch, capfd):
    """`frbench ... | head -1`: the reader goes away mid-output; no traceback, exit 141 (128 + SIGPIPE) like other tools."""
    from frbench.commands import leaderboard

    def closed_pipe(args):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setattr(leaderboard, "run_leaderboard", closed_pipe)
    assert main(["leaderboard"]) == 141
    assert capfd.readouterr().err == ""
