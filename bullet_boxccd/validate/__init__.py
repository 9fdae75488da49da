"""Validation of the solver at scale (``boxccd validate``).

* ``families``: seeded query families (the stress families, vectorised).
* ``checker``: an independent checker of the solver's answers (separating axes, exact
  interval bounds along fixed axes, overlap witnesses; float64, then mpmath).
* ``casefile``: failures as replayable 20-digit JSON cases (``boxccd toi FILE``).
* ``shards``: shards of queries (content fixed by seed and shard index), their tallies,
  and the ``validate`` driver.
* ``report``: the JSON-lines report a run appends to and resumes from.
* ``runner``: runs tasks in-process (``workers=0``) or on Ray (``bullet_boxccd._ray``).
* ``tables``: markdown tables for the command line.

``report``, ``runner`` and ``tables`` also serve ``boxccd sweep``, the plugin's trade-off
grid (``bullet_boxccd.pybullet_ccd.tradeoff``). Nothing here imports pybullet.
"""
