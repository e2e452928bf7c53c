"""Training trained agents on polyenvs with Stable-Baselines3 and sb3-contrib (the ``train`` extra).

- :mod:`polyenvs.training.vec_adapter`: an SB3 ``VecEnv`` over a native Gymnasium vector env (same-step autoreset),
  and :func:`~polyenvs.training.vec_adapter.make_training_vec_env`, which picks it or SB3's ``DummyVecEnv``.
- :mod:`polyenvs.training.config`: RL Zoo-format YAML configs (``configs/<algo>.yml``), parsed safely.
- the algorithms ``train`` knows and the action spaces each accepts are :mod:`baselines.algorithms`'s table.
- :mod:`polyenvs.training.callbacks`: TensorBoard logging of the task metrics of finished episodes.
- :mod:`polyenvs.training.train`: :func:`~polyenvs.training.train.train` of a
  :class:`~polyenvs.training.train.TrainRequest`, one run into one output directory.
- :mod:`polyenvs.training.sweep`: a sweep's jobs (train, then evaluate) on a local process pool or Ray.
- the ``polyenvs train`` and ``polyenvs sweep`` subcommands are :mod:`polyenvs.commands.train` and
  :mod:`polyenvs.commands.sweep`.

Nothing here is imported by ``import polyenvs``; the modules import torch and Stable-Baselines3 only when used.

The output directory of a run (a contract the evaluator, the leaderboard and sweeps rely on)::

    <out>/model.zip          model.save() of the algorithm
    <out>/vecnormalize.pkl   VecNormalize statistics, only when the config normalises
    <out>/run.json           env_id, algo, seed, timesteps, requested_timesteps, n_envs, env_kwargs, hyperparams,
                             command, versions, git_commit, wall_clock_s, completed (false while running or if
                             interrupted)
    <out>/tb/                TensorBoard logs

The model, its statistics and run.json's timesteps are saved every ``DEFAULT_CHECKPOINT_EVERY`` timesteps while a
run trains (and on Ctrl-C), so an interrupted run (run.json: completed false) resumes from there
(``TrainRequest(..., resume=True)``, ``polyenvs train --resume``; a sweep's re-run does it by itself).
"""

#: Save the model this often (timesteps) while training, so that a killed run can resume; light to import.
DEFAULT_CHECKPOINT_EVERY = 100_000
