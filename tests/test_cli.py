"""The ``boxccd`` command's surface: --version, each demo's own --help, toi's case-file
errors (one line, exit status 2, no traceback), and validate / sweep refusing to start
without their extras (one line naming the install command from the checkout)."""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest

from bullet_boxccd import cli

ROOT = Path(__file__).resolve().parent.parent
SCALE = 'pip install ".[scale]"'


def run_main(capsys, *argv):
    """cli.main(argv): (exit status, stdout, stderr), SystemExit included."""
    try:
        code = cli.main(list(argv))
    except SystemExit as e:
        code = e.code
    out = capsys.readouterr()
    return code, out.out, out.err


def boxccd(*argv):
    """The installed command, run outside the checkout (whose bullet_boxccd/ has no built core)."""
    with tempfile.TemporaryDirectory() as cwd:
        return subprocess.run([sys.executable, "-m", "bullet_boxccd", *argv], capture_output=True, text=True,
                              cwd=cwd, timeout=120)


# ------------------------------------------------------------------ --version, demo options
def test_version(capsys):
    code, out, _ = run_main(capsys, "--version")
    assert code == 0 and out.strip() == f"boxccd {version('bullet_boxccd')}"


DEMO_OPTIONS = {
    "wall": ["--phases", "--speed", "--thickness", "--out"],
    "plank": ["--phases", "--out"],
    "bullets": ["--phases", "--out"],
    "rain": ["--pieces", "--runs", "--out"],
    "solver": ["--out"],
}


def test_every_demo_is_covered():
    assert set(DEMO_OPTIONS) == set(cli.DEMOS)


@pytest.mark.parametrize("name", sorted(DEMO_OPTIONS))
def test_demo_help_shows_its_own_options(name, capsys):
    code, out, err = run_main(capsys, "demo", name, "--help")
    assert code == 0 and not err
    assert out.startswith(f"usage: boxccd demo {name} ")
    for option in DEMO_OPTIONS[name]:
        assert option in out
    doc, options = cli.demo_spec(name)
    assert doc.split("\n")[0][:40] in out  # the demo's docstring describes it
    assert [f"--{k}" for k in options] + ["--out"] == DEMO_OPTIONS[name]


def test_demo_help_from_the_console_command():
    r = boxccd("demo", "wall", "--help")
    assert r.returncode == 0, r.stderr
    for option in DEMO_OPTIONS["wall"]:
        assert option in r.stdout
    assert "(default: 100)" in r.stdout  # the speed's default


@pytest.mark.parametrize("argv, message", [
    (["demo", "wall", "--speed", "0"], "expected a finite number > 0"),
    (["demo", "wall", "--thickness", "inf"], "expected a finite number > 0"),
    (["demo", "wall", "--phases", "2.5"], "expected a whole number"),
    (["demo", "plank", "--speed", "50"], "unrecognized arguments: --speed"),
    (["demo", "nosuch"], "invalid choice"),
])
def test_bad_demo_option_is_a_usage_error(argv, message, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run_main(capsys, *argv)
    assert code == 2 and message in err
    assert not list(tmp_path.iterdir())  # nothing ran


def test_demo_list(capsys):
    code, out, _ = run_main(capsys, "demo", "--list")
    assert code == 0 and all(name in out for name in cli.DEMOS)


def test_demo_options_reach_the_script(monkeypatch, capsys):
    seen = {}
    monkeypatch.setattr(cli, "run_demo", lambda name, args: seen.update(name=name, args=args))
    assert cli.main(["demo", "wall", "--speed", "50", "--out", "pics"]) == 0
    assert seen == {"name": "wall", "args": ["--phases", "24", "--speed", "50.0", "--thickness", "0.01",
                                             "--out", "pics"]}


# ------------------------------------------------------------------ toi
def case(**change):
    static = np.stack([np.eye(4), np.zeros((4, 4)), np.zeros((4, 4))])
    moving = static.copy()
    moving[0, 0, 3], moving[1, 0, 3] = 3.0, -4.0  # from x = 3 at 4 per unit t
    c = {"lo_a": [-1, -1, -1], "hi_a": [1, 1, 1], "coeffs_a": static.tolist(),
         "lo_b": [-0.5, -0.5, -0.5], "hi_b": [0.5, 0.5, 0.5], "coeffs_b": moving.tolist(), "t_range": [0, 1]}
    c.update(change)
    return {k: v for k, v in c.items() if v is not None}


def test_toi_help_documents_the_case_format(capsys):
    code, out, _ = run_main(capsys, "toi", "--help")
    assert code == 0
    for word in ("lo_a", "hi_a", "coeffs_a", "lo_b", "hi_b", "coeffs_b", "t_range", "3 x 4 x 4", "C0 + C1 t + C2 t^2"):
        assert word in out


def test_toi_solves_a_case(tmp_path, capsys):
    f = tmp_path / "case.json"
    f.write_text(json.dumps(case()))
    code, out, _ = run_main(capsys, "toi", str(f))
    assert code == 0
    got = json.loads(out)
    assert got["hit"] and got["t"] == pytest.approx(0.375)  # B's face x = 3 - 4t - 0.5 meets A's at x = 1


BAD_CASES = {
    "missing file": (None, "cannot read"),
    "bad JSON": ("{'lo_a': [0, 0, 0]", "is not JSON"),
    "not an object": ("[1, 2, 3]", "expected a JSON object"),
    "missing key": (json.dumps(case(coeffs_b=None)), "no coeffs_b"),
    "wrong shape": (json.dumps(case(lo_a=[0, 0])), "lo_a has shape (2,), expected (3,)"),
    "wrong motion shape": (json.dumps(case(coeffs_a=np.zeros((3, 4)).tolist())), "coeffs_a has shape (3, 4)"),
    "not numbers": (json.dumps(case(hi_b=["a", "b", "c"])), "hi_b must hold numbers"),
    "bad t_range": (json.dumps(case(t_range=[0, 1, 2])), "t_range has shape (3,)"),
    "lo above hi": (json.dumps(case(lo_a=[2, -1, -1])), "case.json: "),
}


@pytest.mark.parametrize("kind", sorted(BAD_CASES))
def test_bad_case_file_is_a_one_line_error(kind, tmp_path, capsys):
    text, message = BAD_CASES[kind]
    f = tmp_path / "case.json"
    if text is not None:
        f.write_text(text)
    code, out, err = run_main(capsys, "toi", str(f))
    assert code == 2 and not out
    assert err.startswith("boxccd toi: error: ") and message in err
    assert err.count("\n") == 1, err


def test_bad_case_file_from_the_console_command(tmp_path):
    r = boxccd("toi", str(tmp_path / "nowhere.json"))
    assert r.returncode == 2
    assert r.stderr.count("\n") == 1 and "Traceback" not in r.stderr and "nowhere.json" in r.stderr
    (tmp_path / "bad.json").write_text(json.dumps(case(lo_b=[[0, 0, 0]])))
    r = boxccd("toi", str(tmp_path / "bad.json"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "lo_b has shape (1, 3)" in r.stderr


# ------------------------------------------------------------------ validate / sweep extras
@pytest.fixture
def no_work(monkeypatch, tmp_path):
    """Fail if validate or sweep starts; run in an empty directory."""
    from bullet_boxccd.pybullet_ccd.tradeoff import grid
    from bullet_boxccd.validate import shards

    def started(*args, **kwargs):
        raise AssertionError("the command started its work")

    monkeypatch.setattr(shards, "validate", started)
    monkeypatch.setattr(grid, "sweep", started)
    monkeypatch.chdir(tmp_path)
    return tmp_path


@pytest.mark.parametrize("argv, missing", [
    (["validate", "--queries", "10"], ["ray"]),
    (["validate", "--queries", "10", "--workers", "0"], ["mpmath"]),
    (["validate", "--queries", "10"], ["ray", "mpmath"]),
    (["validate", "--queries", "10", "--workers", "0", "--address", "auto"], ["ray"]),
    (["sweep", "--quick"], ["ray"]),
    (["sweep", "--quick", "--workers", "0"], ["matplotlib"]),
    (["sweep", "--quick", "--report", "r.jsonl"], ["ray", "matplotlib"]),
])
def test_missing_extras_stop_before_any_work(argv, missing, monkeypatch, no_work, capsys):
    for m in missing:
        monkeypatch.setitem(sys.modules, m, None)  # its import fails
    code, out, err = run_main(capsys, *argv)
    assert code == 2 and not out
    assert err.count("\n") == 1, err
    assert err.startswith(f"boxccd {argv[0]}: error: needs {' and '.join(missing)}") and SCALE in err
    assert "bullet_boxccd[" not in err  # not on an index
    assert not list(no_work.iterdir())  # no report, no case directory, no CSV


def test_without_ray_in_process_runs_and_without_tqdm_says_so(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "ray", None)
    monkeypatch.setitem(sys.modules, "tqdm", None)
    monkeypatch.chdir(tmp_path)
    code, out, err = run_main(capsys, "validate", "--queries", "20", "--families", "scale", "--workers", "0")
    assert code == 0 and "validated 20 queries" in out
    assert f"boxccd validate: no progress bar, tqdm is not installed ({SCALE}" in err


def test_unknown_family_is_a_usage_error(no_work, capsys):
    code, _, err = run_main(capsys, "validate", "--families", "scale,nosuch", "--workers", "0")
    assert code == 2 and "unknown families ['nosuch']" in err


def test_no_module_suggests_installing_from_an_index():
    """The package is not on an index: install commands name the checkout (".[scale]")."""
    files = [*(ROOT / "bullet_boxccd").rglob("*.py"), *(ROOT / "demos").glob("*.py"), ROOT / "pyproject.toml"]
    assert [str(f) for f in files if "bullet_boxccd[" in f.read_text()] == []
