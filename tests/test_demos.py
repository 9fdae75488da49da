"""Smoke test of the demos (the README's first command runs `boxccd demo wall`): each
runs headless on a smaller scene, asserts its own outcome and saves its picture."""

from __future__ import annotations

import os

import pytest

from bullet_boxccd.cli import main

DEMOS = [
    ("wall", ["--phases", "8"], "thin_wall.png"),
    ("plank", ["--phases", "10"], "spinning_plank.png"),
    ("bullets", ["--phases", "6"], "two_bullets.png"),
    ("rain", ["--pieces", "9", "--runs", "1"], "box_rain.png"),
    ("solver", [], None),
]


@pytest.mark.parametrize("name, args, picture", DEMOS)
def test_demo_runs_and_asserts_its_outcome(name, args, picture, tmp_path, capsys):
    out = tmp_path / "pictures"
    assert main(["demo", name, *args] + (["--out", str(out)] if picture else [])) == 0
    printed = capsys.readouterr().out
    assert "BoxCCD" in printed or "first contact" in printed
    if picture:
        png = out / picture
        assert png.exists() and os.path.getsize(png) > 1000
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
