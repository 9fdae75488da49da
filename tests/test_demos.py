"""Smoke test of the demos (the README's first command runs `boxccd demo wall`): each
runs headless on a smaller scene, asserts its own outcome (BoxCCD loses nothing,
plain pybullet does) and saves its picture: a matplotlib figure of plain pybullet
and BoxCCD side by side (the solver's: its route and the contact)."""

from __future__ import annotations

import struct
import sys

import pytest

from bullet_boxccd.cli import main

DEMOS = [
    ("wall", ["--phases", "8"], "thin_wall.png"),
    ("plank", ["--phases", "10"], "spinning_plank.png"),
    ("bullets", ["--phases", "6"], "two_bullets.png"),
    ("rain", ["--pieces", "9", "--runs", "1"], "box_rain.png"),
    ("solver", [], "solver_contact.png"),
]


@pytest.mark.parametrize("name, args, picture", DEMOS)
def test_demo_runs_and_asserts_its_outcome(name, args, picture, tmp_path, capsys):
    out = tmp_path / "pictures"
    assert main(["demo", name, *args, "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "BoxCCD" in printed or "first contact" in printed
    png = out / picture
    assert f"picture: {png}" in printed
    data = png.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    width, height = struct.unpack(">II", data[16:24])
    assert width >= 1000 and height >= 500 and len(data) > 50_000  # a drawn figure, not a blank


def test_demo_without_matplotlib_says_so_before_running(monkeypatch, tmp_path, capsys):
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(SystemExit) as e:
        main(["demo", "wall", "--phases", "2", "--out", str(tmp_path)])
    assert "matplotlib, which is not installed: pip install matplotlib" in str(e.value)
    assert "\n" not in str(e.value)
    assert "tunneled" not in capsys.readouterr().out and not list(tmp_path.iterdir())
