"""What every plugin benchmark prints about the code it measured, and reads of its command line."""

from __future__ import annotations

import ast
import csv
import os
import subprocess

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def code_version() -> str:
    """The commit of the tree that is measured, and whether bullet_boxccd differs from it (read-only git)."""
    try:
        head = subprocess.run(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                              check=True).stdout.strip()
        dirty = subprocess.run(["git", "-C", ROOT, "status", "--porcelain", "--", "bullet_boxccd"],
                               capture_output=True, text=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown (no git)"
    return head + (" + uncommitted changes in bullet_boxccd/" if dirty else "")


def knobs(text: str) -> dict:
    """BoxCCD keyword arguments from "k=v,k2=v2" (each value a Python literal, else a string)."""
    kw = {}
    for item in text.split(","):
        if item.strip():
            k, v = item.split("=", 1)
            try:
                kw[k.strip()] = ast.literal_eval(v.strip())
            except (ValueError, SyntaxError):
                kw[k.strip()] = v.strip()
    return kw


def write_csv(path: str, rows: list) -> None:
    """Rows (dicts with the same keys) to a CSV at path, floats to 6 significant digits."""
    os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
    with open(path, "w", newline="") as f:
        wr = csv.DictWriter(f, fieldnames=list(rows[0]))
        wr.writeheader()
        for row in rows:
            wr.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in row.items()})
