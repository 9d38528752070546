"""Hostile and unlucky runs beyond one refused command: a run folder that names code, locks another
user prepared, two trainings at once, a full disk, script in a report, a viewer that never answers,
a net too large to analyse. One test (at least) per class of defect; the one-line refusals are rows
of ``test_hostile_input``'s table."""

from __future__ import annotations

import fcntl
import json
import os
import shutil
import socket
import stat
import subprocess
import sys
import tempfile
import textwrap
import threading
import time
from html.parser import HTMLParser
from pathlib import Path

import pytest

from multiform.cli import main  # noqa: F401  (the process the tests start imports it)
from multiform.lock import exclusive, lock_name
from multiform.task import load_task

from .report.test_page import pendulum_metrics
from .test_hostile_input import EVIL, _chain, lab, run, snapshot, work  # noqa: F401  (fixtures)

task = load_task("pendulum")

SRC = str(Path(__file__).resolve().parents[1] / "src")


def cli(*argv: str, timeout: float = 300, env: dict | None = None, code: str = "") -> subprocess.CompletedProcess:
    """``multiform ARGV`` in a process of its own (a crash shows as a signal, not as this test dying)."""
    prog = code or "import sys; from multiform.cli import main; sys.exit(main(sys.argv[1:]))"
    e = {**os.environ, "PYTHONPATH": SRC + os.pathsep + os.environ.get("PYTHONPATH", ""), **(env or {})}
    return subprocess.run([sys.executable, "-c", prog, *argv], capture_output=True, text=True, timeout=timeout, env=e)


def error_lines(err: str) -> list[str]:
    """stderr's lines without progress bars (tqdm redraws with carriage returns)."""
    return [line.split("\r")[-1] for line in err.splitlines() if line.split("\r")[-1].strip()
            and "%|" not in line.split("\r")[-1]]


# -- 1. a run folder is data ------------------------------------------------------------------------

def _run_folder(lab: Path, out: Path, task_name: str, task_spec: str) -> Path:
    """A finished run of the hostile lab's model: its metrics, evaluation trials and model."""
    out.mkdir()
    shutil.copytree(lab / "model", out / "model")
    specs = task.evaluation_specs(2, 0, 0.5)
    detail = [{"seed": s.seed, "success": True, "self_success": True, "pushed": s.push is not None, "fired": ["t0"]}
              for s in specs]
    cfg = {"eval_trials": 2, "seed": 0, "push_fraction": 0.5, "videos": False, "inverse_model": False, "workers": 2}
    (out / "metrics.json").write_text(json.dumps({"skill": "pendulum", "task": task_name, "task_spec": task_spec,
                                                  "config": cfg, "scenarios": {}, "revisions": [],
                                                  "success_rate": {"successes": 2, "trials": 2, "rate": 1.0,
                                                                   "low": 0.34, "high": 1.0}}))
    (out / "evaluation_trials.json").write_text(json.dumps({"multiform": detail}))
    return out


def test_redraw_runs_the_task_the_user_names_never_one_the_folder_names(work, capsys):
    marker = work / "imported"
    (work / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\nT = None\n")
    # the folder names a module and a file; the redraw runs the bundled task it also names, or the user's
    for name, (task_name, spec, extra) in {"r1": ("pendulum", f"{EVIL}:T", []),
                                           "r2": (str(work / "evil.py") + ":T", str(work / "evil.py") + ":T",
                                                  ["--task", "pendulum"])}.items():
        run_dir = _run_folder(work, work / name, task_name, spec)
        assert run(["report", str(run_dir), "--redraw", *extra]) == 0, capsys.readouterr().err
        metrics = json.loads((run_dir / "metrics.json").read_text())
        plot = metrics["artifacts"]["plots"]["success_trial"]
        assert (run_dir / plot["file"]).stat().st_size > 0 and plot["seed"] == task.evaluation_specs(2, 0, 0.5)[1].seed
        assert (run_dir / "report.html").exists() and (run_dir / "nets" / "net_v0.svg").exists()
    # the folder alone cannot make it run the file
    run_dir = _run_folder(work, work / "r3", str(work / "evil.py") + ":T", str(work / "evil.py") + ":T")
    before = snapshot(run_dir)
    assert run(["report", str(run_dir), "--redraw"]) == 2
    assert "--task" in capsys.readouterr().err and snapshot(run_dir) == before
    assert not marker.exists() and EVIL not in sys.modules


def test_the_report_pictures_take_plain_data_not_the_job():
    """report.artifacts imports nothing of multiform.job (once an import cycle)."""
    probe = cli(code="import sys, multiform.report.artifacts; print(sorted(m for m in sys.modules "
                     "if m.startswith('multiform.job')))")
    assert probe.returncode == 0 and probe.stdout.strip() == "[]", probe.stderr


# -- 2. locks that cannot be turned against their user --------------------------------------------

@pytest.fixture()
def lock_home(tmp_path, monkeypatch):
    """A temporary directory and a cache folder of the test's own, as the lock module finds them."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    monkeypatch.delenv("XDG_RUNTIME_DIR", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    (tmp_path / "tmp").mkdir()
    (tmp_path / "cwd").mkdir()
    monkeypatch.chdir(tmp_path / "cwd")
    victim = tmp_path / "victim.txt"
    victim.write_bytes(bytes(range(256)) * 5 + b"precious")           # 1,288 bytes
    return tmp_path, victim


def _prepared(tmp_path: Path, target: Path, victim: Path, mode: int, owner: int | None) -> Path:
    """The lock folder of the temporary directory made first, by "another user": wrong mode or owner,
    the target's lock file a symlink to the victim."""
    folder = tmp_path / "tmp" / f"multiform-locks-{os.geteuid()}"
    folder.mkdir()
    (folder / lock_name(target)).symlink_to(victim)
    os.chmod(folder, mode)
    if owner is not None:
        os.chown(folder, owner, owner)
    return folder


@pytest.mark.parametrize("who", ["open_to_others", "another_user"])
def test_a_lock_folder_another_user_prepared_is_passed_over(lock_home, who, capsys):
    tmp_path, victim = lock_home
    if who == "another_user" and os.geteuid() != 0:
        pytest.skip("making a folder another user's needs root (CI runs as root)")
    before = victim.read_bytes()
    target, other = Path("run").resolve(), Path("other").resolve()
    folder = _prepared(tmp_path, target, victim, 0o777 if who == "open_to_others" else 0o700,
                       None if who == "open_to_others" else 65534)
    # the other user also holds a lock in their folder: it refuses nothing of ours
    held = os.open(folder / lock_name(other), os.O_RDWR | os.O_CREAT, 0o600)
    fcntl.flock(held, fcntl.LOCK_EX)
    try:
        with exclusive(other):
            pass
        Path("run").mkdir()
        Path("run", "metrics.json").write_text(json.dumps(pendulum_metrics()))
        assert run(["report", "run"]) == 0, capsys.readouterr().err
        assert Path("run", "report.html").exists()
        assert (tmp_path / "cache" / "multiform" / "locks" / lock_name(target)).is_file()
    finally:
        os.close(held)
    assert victim.read_bytes() == before and os.path.islink(folder / lock_name(target))
    mode = stat.S_IMODE(os.stat(tmp_path / "cache" / "multiform" / "locks").st_mode)
    assert mode == 0o700


def test_a_symlinked_lock_file_in_ones_own_folder_is_refused_not_followed(lock_home, capsys):
    tmp_path, victim = lock_home
    before = victim.read_bytes()
    folder = tmp_path / "tmp" / f"multiform-locks-{os.geteuid()}"
    folder.mkdir(mode=0o700)
    out = Path("d.h5").resolve()
    (folder / lock_name(out)).symlink_to(victim)
    assert run(["record", "pendulum", "--demos", "1", "-o", "d.h5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "d.h5" in err and "symlink" in err
    assert victim.read_bytes() == before and not out.exists()


def test_a_lock_is_written_over_never_truncated_and_names_its_holder(lock_home):
    tmp_path, _ = lock_home
    with exclusive("x"):
        name = tmp_path / "tmp" / f"multiform-locks-{os.geteuid()}" / lock_name(Path("x").resolve())
        assert name.read_text().strip() == str(os.getpid())
        fd = os.open(name, os.O_RDWR)
        with pytest.raises(BlockingIOError):
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        os.close(fd)
    assert stat.S_IMODE(os.stat(name.parent).st_mode) == 0o700


# -- 3. staging that belongs to one writer --------------------------------------------------------

def test_a_refused_second_train_leaves_the_first_ones_work_and_a_stale_one_blocks_nothing(lab, tmp_path, monkeypatch,
                                                                                          capsys):
    import multiform.job as job
    monkeypatch.chdir(tmp_path)
    first = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import time
        from multiform.model import staged_model_dir
        with staged_model_dir({str(tmp_path / 'm')!r}) as partial:
            (partial / "work").write_text("an hour of training")
            print(partial, flush=True)
            time.sleep(120)
    """)], stdout=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": SRC})
    try:
        partial = Path(first.stdout.readline().strip())
        assert partial.name.startswith(".m.partial-") and partial.parent == tmp_path
        assert run(["train", "pendulum", str(lab / "demos.h5"), "-o", "m"]) == 2
        err = capsys.readouterr().err
        assert f"in use by PID {first.pid}" in err and ".partial" not in err
        assert (partial / "work").read_text() == "an hour of training"
    finally:
        first.kill()            # killed: its staging folder stays behind, stale
        first.wait()
        first.stdout.close()
    assert partial.is_dir()
    (partial / "skill.yaml").write_text("skill: something else\n")

    def train(model, **kw):     # what matters here is the directory, not the fit
        model.update_manifest(training={"laws": {}})
    monkeypatch.setattr(job, "train_model", train)
    assert run(["train", "pendulum", str(lab / "demos.h5"), "-o", "m"]) == 0
    out, err = capsys.readouterr()
    assert (tmp_path / "m" / "model.json").exists() and ".partial" not in out + err
    assert (partial / "work").exists()          # the stale folder is its maker's: nobody else removes it
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".m.partial")) == [partial.name]


# -- 4. and 11. a full disk: exit 2, one line naming the file, nothing left, no crash ----------------

@pytest.fixture()
def full_disk(tmp_path):
    """A 2 MB tmpfs with ``free`` bytes left (call it), unmounted afterwards."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("mounting a tmpfs is not allowed here")

    def fill(free: int) -> Path:
        total = shutil.disk_usage(disk).free
        (disk / "fill").write_bytes(b"\0" * max(0, total - free))
        return disk
    yield fill
    subprocess.run(["umount", "-l", str(disk)], check=False)


def _refused_for_lack_of_space(p: subprocess.CompletedProcess, name: str) -> None:
    assert p.returncode == 2, (p.returncode, p.stderr[-3000:])
    lines = error_lines(p.stderr)
    assert len(lines) == 1 and lines[0].startswith("multiform: error:") and name in lines[0], p.stderr[-3000:]
    assert "No space left" in lines[0] and "Traceback" not in p.stderr


def test_record_demo_and_teleop_on_a_full_disk(full_disk, tmp_path):
    disk = full_disk(20_000)
    _refused_for_lack_of_space(cli("record", "pendulum", "--demos", "1", "--workers", "1", "-o", str(disk / "d.h5")),
                               "d.h5")
    assert sorted(os.listdir(disk)) == ["fill"]
    _refused_for_lack_of_space(cli("demo", "pendulum", "--demos", "1", "--workers", "1", "--no-video",
                                   "-o", str(disk / "run")), "demos.h5")
    assert sorted(os.listdir(disk)) == ["fill"]          # the run folder it made is gone again
    teleop = textwrap.dedent("""
        import os, sys
        os.environ["SDL_VIDEODRIVER"] = os.environ["SDL_AUDIODRIVER"] = "dummy"
        import pygame
        from multiform import cli
        def script(stage, i):
            keys = {0: [pygame.K_RIGHT], 40: [pygame.K_ESCAPE]}.get(i, []) if stage == "demo" else [pygame.K_s]
            for k in keys:
                pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=k, mod=0, unicode="", scancode=0))
        cli._TELEOP_SCRIPT = script
        sys.exit(cli.main(sys.argv[1:]))
    """)
    _refused_for_lack_of_space(cli("teleop", "pendulum", "-o", str(disk / "t.h5"), "--keyboard", "--time-scale",
                                   "100", "--max-duration", "5", code=teleop), "t.h5")
    assert sorted(os.listdir(disk)) == ["fill"]


def test_evaluate_on_a_full_disk_names_the_file_and_leaves_no_folder(full_disk, lab):
    disk = full_disk(0)
    p = cli("evaluate", str(lab / "model"), "--trials", "2", "--workers", "1", "--out", str(disk / "ev"))
    _refused_for_lack_of_space(p, str(disk / "ev"))
    assert sorted(os.listdir(disk)) == ["fill"]


# -- 5. every string that reaches the report page is escaped, every link checked --------------------

PAYLOAD = "<script>alert(1)</script><img src=x onerror=alert(2)>'\""
BAD_URLS = ["javascript:alert(1)", "data:text/html,<script>alert(3)</script>", "/etc/passwd", "../../x.png",
            "https://example.org/x.png", "JaVaScRiPt:alert(4)", " javascript:alert(5)"]


class _Tags(HTMLParser):
    def __init__(self):
        super().__init__()
        self.tags: list[tuple[str, dict]] = []

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))


def _poison(x, keys: bool):
    """Every string of ``x`` (values; with ``keys`` the keys too) replaced by the payload around it."""
    if isinstance(x, dict):
        return {(f"{PAYLOAD}{k}" if keys else k): _poison(v, keys) for k, v in x.items()}
    if isinstance(x, list):
        return [_poison(v, keys) for v in x]
    return f"{PAYLOAD}{x}" if isinstance(x, str) else x


@pytest.mark.parametrize("where", ["values", "keys", "numbers_as_text", "urls"])
def test_every_string_from_metrics_reaches_the_page_escaped(where):
    from multiform.report.page import page_html
    m = pendulum_metrics()
    m["artifacts"]["views"] = {"a": {"file": "view/a.rrd", "caption": "a view"}}
    m["artifacts"]["videos"] = {"s": {"file": "videos/s.mp4", "caption": "a video"}}
    if where in ("values", "keys"):
        m = _poison(m, keys=where == "keys")
    elif where == "numbers_as_text":
        m["demos"]["count"] = PAYLOAD
        m["practice_trials"] = PAYLOAD
        m["artifacts"]["plots"]["recovery_trial"]["figure"] = PAYLOAD
        m["timings"]["total_s"] = 1.0
    else:
        url = iter(BAD_URLS * 3)
        m["artifacts"]["views"] = {k: {"file": next(url), "caption": k} for k in "abc"}
        m["artifacts"]["videos"] = {k: {"file": next(url), "caption": k} for k in "abc"}
        m["artifacts"]["plots"]["recovery_trial"]["file"] = next(url)
        m["artifacts"]["plots"]["evaluation"] = next(url)
        m["artifacts"]["nets"] = [{"file": u, "caption": "net"} for u in BAD_URLS]
        m["scenarios"]["a_strict"]["plot"] = next(url)
    try:
        page = page_html(m)
    except (KeyError, TypeError, ValueError):
        assert where == "keys"        # keys the page looks up, changed: refused (report says malformed), not shown
        return
    parser = _Tags()
    parser.feed(page)
    tags = [t for t, _ in parser.tags]
    assert tags.count("script") == 1 and tags[0] == "html"
    assert all(not k.startswith("on") for _, attrs in parser.tags for k in attrs)
    assert all(attrs.get("src") != "x" for _, attrs in parser.tags)
    links = [v for _, attrs in parser.tags for k, v in attrs.items() if k in ("src", "href")]
    assert all(":" not in v and not v.startswith("/") and ".." not in v for v in links), links
    if where == "numbers_as_text":          # the files are the run's: shown, the text beside them escaped
        assert len(links) == 6 and page.count("&lt;script&gt;alert(1)&lt;/script&gt;") == 4
    if where == "values":
        assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page


# -- 6. a viewer never blocks a trial ----------------------------------------------------------------

@pytest.fixture()
def silent_viewer():
    """A TCP server that accepts connections and never answers (a viewer behind a dead proxy)."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(16)
    conns, stop = [], threading.Event()

    def accept():
        srv.settimeout(0.2)
        while not stop.is_set():
            try:
                conns.append(srv.accept()[0])
            except OSError:
                pass
    t = threading.Thread(target=accept, daemon=True)
    t.start()
    yield f"rerun+http://127.0.0.1:{srv.getsockname()[1]}/proxy"
    stop.set()
    t.join()
    for c in conns:
        c.close()
    srv.close()


def test_practice_with_a_viewer_that_never_answers_returns_and_releases_the_model(work, silent_viewer):
    pytest.importorskip("rerun")
    t0 = time.perf_counter()
    p = cli("practice", str(work / "model"), "--max-trials", "1", "--view", silent_viewer, "--out", str(work / "p"),
            timeout=240)
    took = time.perf_counter() - t0
    assert p.returncode == 0, p.stderr[-2000:]
    assert "multiform: the view: the viewer at" in p.stderr and took < 90, took
    assert (work / "p" / "view" / "trial_0000.rrd").stat().st_size > 0
    assert not [f for f in os.listdir(work / "p" / "view") if f.startswith(".")]
    with exclusive(work / "model"):
        pass


# -- 7. the analysis is bounded in time and memory ---------------------------------------------------

MEASURED = ("import sys, time; from multiform.cli import main; t = time.perf_counter(); code = main(sys.argv[1:]); "
            "hwm = [l.split()[1] for l in open('/proc/self/status') if l.startswith('VmHWM:')]; "
            "print(f'RUN {time.perf_counter() - t:.2f} {hwm[0]}', file=sys.stderr); sys.exit(code)")


def _measured(*argv: str) -> tuple[subprocess.CompletedProcess, float, float]:
    """The command in a process of its own: the process, its wall time (start-up included) and its
    peak memory in MB (the address space's high-water mark: ``ru_maxrss`` would include the forking
    parent's)."""
    if not Path("/proc/self/status").exists():
        pytest.skip("needs Linux's /proc to measure a process's peak memory")
    t0 = time.perf_counter()
    p = cli(*argv, code=MEASURED, timeout=120)
    wall = time.perf_counter() - t0
    line = next(x for x in p.stderr.splitlines() if x.startswith("RUN "))
    return p, wall, int(line.split()[2]) / 1024


def test_check_of_a_10000_place_chain_returns_within_10_s_and_1_gb(tmp_path):
    (tmp_path / "chain.yaml").write_text(_chain(10_000))
    p, seconds, mb = _measured("check", str(tmp_path / "chain.yaml"))
    assert p.returncode == 0 and "10000 states" in p.stdout and "check: ok" in p.stdout, p.stdout + p.stderr
    assert seconds < 10 and mb < 1024, (seconds, mb)
    p, seconds, mb = _measured("check", str(tmp_path / "chain.yaml"), "--max-states", "100")
    assert p.returncode == 2 and "stopped at the cap of 100 states" in p.stdout
    assert seconds < 10 and mb < 1024, (seconds, mb)


def test_check_stops_at_its_time_budget(tmp_path):
    """A chain that adds a token at every step needs Karp-Miller's ancestor checks, quadratic in its
    length: the time budget ends it."""
    text = _chain(4000).replace("out: [P", "out: [sink, P").replace("places:\n", "places:\n  sink: {label: s}\n")
    (tmp_path / "grow.yaml").write_text(text)
    p, seconds, mb = _measured("check", str(tmp_path / "grow.yaml"), "--max-seconds", "1")
    assert p.returncode == 2 and "time budget" in p.stdout, p.stdout + p.stderr
    assert seconds < 10 and mb < 1024, (seconds, mb)


def test_a_yaml_alias_bomb_is_refused_at_once(tmp_path, capsys):
    from .test_hostile_input import BOMB
    (tmp_path / "bomb.yaml").write_text(BOMB + "skill: x\ndescription: *i\n")
    t0 = time.perf_counter()
    assert run(["check", str(tmp_path / "bomb.yaml")]) == 2
    assert time.perf_counter() - t0 < 2 and "aliases" in capsys.readouterr().err


# -- 8. numbers range-checked where they enter ------------------------------------------------------

def test_a_skill_file_bounds_the_length_of_a_trial():
    from multiform.errors import InvalidInput
    from multiform.petri.skillfile import parse_skill
    from .test_hostile_input import PENDULUM_TEXT
    for old, new, element in (("max_duration: 30.0", "max_duration: 1e12", "max_duration"),
                              ("max_duration: 30.0", "max_duration: 1001", "max_duration"),
                              ("control_rate: 1000", "control_rate: 1e6", "control_rate")):
        with pytest.raises(InvalidInput, match=element):
            parse_skill(PENDULUM_TEXT.replace(old, new, 1))
    assert parse_skill(PENDULUM_TEXT.replace("max_duration: 30.0", "max_duration: 1000", 1)).max_duration == 1000


def test_demonstrations_are_checked_after_their_action_scale(work):
    from multiform.demos.dataset import read_dataset
    from multiform.errors import InvalidInput
    from .test_hostile_input import _action_past_the_scale, _demos
    with pytest.raises(InvalidInput, match=r"demo_0/actions: non-finite value at sample 3 after action_scale"):
        read_dataset(_demos(work, _action_past_the_scale))


# -- 9. bad training data is bad input ----------------------------------------------------------------

def test_training_data_that_cannot_train_a_law_names_the_file_and_the_law(work, capsys):
    from .test_hostile_input import _all_labels_failed, _demos
    demos = _demos(work, _all_labels_failed)
    assert run(["train", "pendulum", demos, "-o", str(work / "m")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"multiform: error: {demos}: laws.swing_up:") and "successful" in err
    assert not (work / "m").exists() and not [p for p in work.iterdir() if ".partial" in p.name]


# -- 11. the smaller ones -----------------------------------------------------------------------------

def test_a_path_with_a_newline_cannot_forge_a_line(tmp_path, capsys):
    forged = "x\nmultiform: error: everything is fine\n\x1b[2J"
    assert run(["check", str(tmp_path / forged)]) == 66          # the file is not there
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "\x1b" not in err and "\\nmultiform: error: everything" in err


def test_a_demos_fifo_in_model_json_is_refused_before_practice_reads_it(work, capsys):
    fifo = work / "d.fifo"
    os.mkfifo(fifo)
    manifest = json.loads((work / "model" / "model.json").read_text())
    manifest["demos"] = str(fifo)
    (work / "model" / "model.json").write_text(json.dumps(manifest))
    done = []
    t = threading.Thread(target=lambda: done.append(run(["practice", str(work / "model"), "--max-trials", "1"])),
                         daemon=True)
    t.start()
    t.join(60)
    if t.is_alive():
        os.close(os.open(fifo, os.O_RDWR))        # unblock the reader, so that the test process can end
        pytest.fail("practice blocked on the FIFO")
    assert done == [2] and "d.fifo" in capsys.readouterr().err
