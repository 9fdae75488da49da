"""Capturing what C code prints (pybullet writes to the process's file descriptors, not to
sys.stdout)."""

import os
import tempfile


class CFile:
    """Everything written to the process's stdout and stderr file descriptors (C-level
    prints included) while inside the ``with``."""

    def __enter__(self):
        self.tmp = tempfile.TemporaryFile(mode="w+b")
        self.saved = [os.dup(1), os.dup(2)]
        for fd in (1, 2):
            os.dup2(self.tmp.fileno(), fd)
        return self

    def __exit__(self, *exc):
        for fd, saved in zip((1, 2), self.saved):
            os.dup2(saved, fd)
            os.close(saved)
        self.tmp.seek(0)
        self.text = self.tmp.read().decode(errors="replace")
        self.tmp.close()
