"""The plugin's cost / accuracy trade-off (``boxccd sweep``, ``benchmarks/tradeoff.py``).

* ``scenes``: the benchmark scene (a settled pile, a thin wall, a ground), its seeded
  shots and one trial of a configuration on it; ``benchmarks/plugin.py`` runs its trials
  too. It imports pybullet.
* ``grid``: the trade-off grid, one (configuration, scene, seed) per task, each in its
  own pybullet client, run in this process or on Ray; its CSV, tables and Pareto plot.
  It runs its tasks and keeps its report with ``validate``'s runner and report (shared
  machinery: nothing of the solver's validation).
"""
