"""AP-lite / physicomimetics swarms: differential-drive robots with four IR sensors, a goal light and
trilateration, as PettingZoo parallel environments (and two single-robot Gymnasium ids).

Paper: Hettiarachchi and Spears, "Physicomimetics for mobile robot obstacle avoidance" (``../shared/seeds/004_*``).

| module | what |
| --- | --- |
| ``platforms`` | the Maxelbot and the X80Pro as parameter sets |
| ``sensors`` | the GP2D12 IR model (the paper's conversion function) and the two reading scales |
| ``core`` | the batched simulation: moves, contacts, beams, trilateration, on a cell list |
| ``layouts`` | walls, start blocks, the hexagonal lattice, seeded obstacle fields |
| ``batch`` | ``SwarmBatch``, the one core (E environments x N robots; E = 1 in the PettingZoo env); ``TaskTerms`` |
| ``env`` | the PettingZoo surface the tasks share |
| ``corridor_v0``, ``obstacle_field_v0``, ``formation_v0`` | the PettingZoo tasks |
| ``single`` | the Gymnasium ids APLiteCorridor-v0 and APLiteObstacleField-v0 |
| ``vector`` | their native vector envs (``gym.make_vec``) |
| ``batched`` | ``SwarmVectorEnv``: E environments x N robots as one vector env of robots (parameter sharing) |
| ``rendering`` | top-down frames |

Modules are imported on demand (``from polyenvs.swarm import formation_v0``), as in PettingZoo's own families.
"""
