"""The tests' oracle. It lives in bullet_boxccd.testing, where the benchmarks use it
too (written apart from the solver: see that module); the tests import it from here."""

from bullet_boxccd.testing import *  # noqa: F401,F403
from bullet_boxccd.testing import __all__  # noqa: F401
