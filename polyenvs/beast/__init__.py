"""The Platonic beasts: spherically symmetric robots with an RRR limb on each face, rolling by tumbles (MuJoCo).

Paper: Pai, Barman and Ralph, "Platonic Beasts: spherically symmetric multilimbed robots"
(``../shared/seeds/002_*.txt``); spec ``../shared/spec/beast.md``.

| module | what |
| --- | --- |
| ``kinematics`` | Tables 1 and 2: limb frames, forward/inverse kinematics, the limb Jacobian, the 12 tumbles (numpy only) |
| ``model`` | the MJCF generated from bounded physical parameters; the start stances (K0 for the 4-beast) |
| ``sensors`` | encoders with backlash, tilt switches, foot contacts with a debounce, servos with a dead band |
| ``kernel`` | a step in one compiled call for a batch: servos, ``mj_step``, sensors, the tasks' rules and metrics |
| ``env`` | the Gymnasium surface on ``MujocoEnv``: actions, observation, divergence, reward terms, metrics |
| ``tasks`` | ``BeastTumbleEnv``, ``BeastRollEnv``, ``BeastTurnEnv``, ``BeastRecoverEnv`` |
| ``vector`` | the native vector env: the batch stepped on threads, the GIL released |
| ``mujoco_extra`` | MuJoCo, Gymnasium's ``MujocoEnv`` and ``mj_step`` for compiled code, or ``DependencyNotInstalled`` |

Importing this package imports nothing heavy; MuJoCo (the ``mujoco`` extra) is loaded by ``model.build_model`` and
by the environment modules, all through ``mujoco_extra``: without the extra, ``gym.make`` of a beast raises
Gymnasium's ``DependencyNotInstalled`` with ``pip install "polyenvs[mujoco]"``, as Gymnasium's MuJoCo environments do.
"""
