"""The evaluation floor: running policies on the environments, and the leaderboard that judges them.

Above the families and the baselines, below training and the command line (``tests/test_layers.py``). Each module
has one subject, and imports only those listed before it:

- :mod:`~polyenvs.evaluation.rollout`: one seeded episode of either kind of environment (Gymnasium, PettingZoo).
- :mod:`~polyenvs.evaluation.episodes`: ``make_env``, ``make_agent`` and ``evaluate`` for the names a user gives,
  checked before any episode runs.
- :mod:`~polyenvs.evaluation.statistics`: the IQM, its bootstrap intervals, the comparison of two policies with the
  training run as the unit, performance profiles.
- :mod:`~polyenvs.evaluation.charts`: the leaderboard's charts and the learning curves, drawn with matplotlib.
- :mod:`~polyenvs.evaluation.protocol`: the leaderboard's seeds, episode counts, layouts and policies.
- :mod:`~polyenvs.evaluation.agents`: the trained agents it finds and loads.
- :mod:`~polyenvs.evaluation.results`: its result files, and the reproduction of the reference results.
- :mod:`~polyenvs.evaluation.run`: its evaluations, one by one or on a process pool.
- :mod:`~polyenvs.evaluation.table`: each environment's rows, ranked by its task score, and their Markdown.
- :mod:`~polyenvs.evaluation.verdict`: whether a trained agent beats the paper's algorithm.
- :mod:`~polyenvs.evaluation.page`: the leaderboard's Markdown page and its charts.
- :mod:`~polyenvs.evaluation.datasets`: demonstration datasets in Minari's format (``polyenvs collect``).
- :mod:`~polyenvs.evaluation.localization`: the localization benchmark, estimators scored on seeded logs
  (``polyenvs localize``).
- :mod:`~polyenvs.evaluation.localization_report`: its convergence table and chart.
"""
