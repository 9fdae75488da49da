"""Validation and trade-off sweeps at scale (``boxccd validate``, ``boxccd sweep``).

* ``families``: seeded query families (the stress families, vectorised).
* ``checker``: an independent checker of the solver's answers (separating axes, exact
  interval bounds along fixed axes, overlap witnesses; float64, then mpmath).
* ``casefile``: failures as replayable 20-digit JSON cases (``boxccd toi FILE``).
* ``shards``: shards of queries (content fixed by seed and shard index), their tallies,
  and the ``validate`` driver.
* ``report``: the JSON-lines report a run appends to and resumes from.
* ``runner``: runs tasks in-process (``workers=0``) or on Ray (``bullet_boxccd._ray``).
* ``sweep``: the plugin's trade-off grid (``benchmarks/tradeoff.py``), one (configuration,
  scene, seed) per task, each in its own pybullet client (the scene and the trial are
  the adapter's: ``pybullet_ccd.scenes``; nothing here imports pybullet).
"""
