"""What the beasts' hand baselines achieve in MuJoCo: the measurements behind the gait's numbers.

Every run goes through the policies' SB3-style ``predict`` (:mod:`baselines.beast`) on the task classes of
:mod:`polyenvs.beast.tasks`, seeded, and reports the tasks' own end-of-episode metrics plus what the controller did:

- ``tumble``: BeastTumble (4-beast), the canonical tumble (1234) with ``RollingGait(max_tumbles=1)``: success rate
  and time to success.
- ``roll``: BeastRoll (4-beast), four tumbles with ``RollingGait(max_tumbles=4)``: the tumble sequence, distance
  along the heading, time, per-tumble advance and time (feasibility study: 155 mm and 17.3 s per tumble at 20 deg/s),
  and the random policy over the same time.
- ``roll6``: the same for the 6-beast (``polyhedron="octahedron"``).
- ``turn``: BeastTurn, ``SharpTurn`` (4-beast with pivot limb 1 and with look-ahead steering; 6-beast): heading
  change.
- ``recover``: BeastRecover (4-beast), ``Righting``: success rate and time to stance.
- ``faults``: the 6-beast with each limb disabled in turn (paper section 5), the rolling gait for 60 s: distance
  along the heading and straight-line displacement.
- ``crawl``: the 6-beast with each limb disabled in turn, walking the quadruped crawl (``Crawl``) with that limb on
  top: from the crawl stance (``baselines.beast.crawl.crawl_stance_qpos``, forward along world +x) for 60 s, and from
  the task's own rolling stance (reorienting first) for 120 s (and at 60 s): whether and when it reoriented,
  distance along the heading, displacement, crawl steps, and whether anything but a foot touched the floor or the
  simulation went unstable.

From the repo root::

    python -m benchmarks.beast_gait [--seeds 10] [--only tumble,roll,...] [--json PATH]
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np

__all__ = ["main", "run_episode"]


def run_episode(
    env, policy, seed: int, max_steps: int, *, until_done: bool = True, reset_options=None, on_step=None
) -> dict:
    """One seeded episode; stops at termination/truncation, ``max_steps``, or when the controller is done/stuck.
    ``on_step(env, info)``, if given, is called after every step."""
    obs, info = env.reset(seed=seed, options=reset_options)
    state, start = None, True
    start_xy = env.unwrapped.data.qpos[:2].copy()
    steps, controller = 0, None
    while steps < max_steps:
        steps += 1
        action, state = policy.predict(obs, state=state, episode_start=np.array([start]))
        start = False
        obs, _, terminated, truncated, info = env.step(action)
        if on_step is not None:
            on_step(env, info)
        controllers = getattr(policy, "_controllers", None)
        controller = controllers.get(int(state[0, 0])) if controllers is not None else None
        if terminated or truncated:
            break
        if until_done and controller is not None and getattr(controller, "phase", "") in ("done", "stuck"):
            break
    out = env.unwrapped.episode_metrics()  # also where the loop, not the episode, ended
    out["steps"] = steps
    out["sim_s"] = steps * 0.01
    out["displacement_m"] = float(np.linalg.norm(env.unwrapped.data.qpos[:2] - start_xy))
    out["sim_unstable"] = bool(info.get("sim_unstable", False))
    if controller is not None and hasattr(controller, "history"):
        out["history"] = ["".join(map(str, t)) for t in controller.history]
        out["phase"] = controller.phase
    return out


def _summary(values) -> str:
    values = np.asarray(values, dtype=float)
    return f"{values.mean():.3f} +- {values.std():.3f} (min {values.min():.3f}, max {values.max():.3f})"


def bench_tumble(seeds):
    from baselines.beast import RollingGait
    from polyenvs.beast.tasks import BeastTumbleEnv

    env = BeastTumbleEnv()
    policy = RollingGait(env.observation_space, env.action_space, max_tumbles=1)
    runs = [run_episode(env, policy, s, 3000) for s in seeds]
    ok = [r for r in runs if r["success"] == 1.0]
    print(f"tumble: {len(ok)}/{len(runs)} canonical tumbles (limbs 1, 4, 2 down, 3 free); ", end="")
    if ok:
        print(
            f"time to success {_summary([r['time_s'] for r in ok])} s, advance {_summary([r['distance_m'] for r in ok])} m"
        )
    return runs


def _roll(seeds, polyhedron, max_steps, tumbles=4, reset_options=None):
    from baselines.base import RandomPolicy
    from baselines.beast import RollingGait
    from polyenvs.beast.tasks import BeastRollEnv

    env = BeastRollEnv(polyhedron=polyhedron)
    policy = RollingGait(env.observation_space, env.action_space, max_tumbles=tumbles)
    runs = []
    for s in seeds:
        r = run_episode(env, policy, s, max_steps, reset_options=reset_options)
        rnd = run_episode(
            env, RandomPolicy(env.observation_space, env.action_space, seed=s), s, r["steps"], until_done=False
        )
        r["random_distance_m"] = rnd["distance_m"]
        runs.append(r)
    full = [r for r in runs if len(r.get("history", [])) == tumbles]
    print(
        f"roll ({polyhedron}): {len(full)}/{len(runs)} runs completed {tumbles} tumbles; sequences "
        f"{sorted({' '.join(r['history']) for r in runs})}"
    )
    print(
        f"  distance along heading {_summary([r['distance_m'] for r in runs])} m in {_summary([r['sim_s'] for r in runs])} s"
    )
    if full:
        print(
            f"  per tumble (completed runs): {_summary([r['distance_m'] / tumbles for r in full])} m, "
            f"{_summary([r['sim_s'] / tumbles for r in full])} s; speed {_summary([r['distance_m'] / r['sim_s'] for r in full])} m/s"
        )
    print(f"  random policy over the same time: {_summary([r['random_distance_m'] for r in runs])} m")
    return runs


def bench_roll(seeds):
    return _roll(seeds, "tetrahedron", 8000)


def bench_roll6(seeds):
    return _roll(seeds, "octahedron", 9000)


def bench_turn(seeds):
    from baselines.beast import SharpTurn
    from polyenvs.beast.tasks import BeastTurnEnv

    out = {}
    cases = [("tetrahedron", 60.0, 1), ("tetrahedron", 60.0, None), ("tetrahedron", -60.0, None)]
    cases += [("tetrahedron", 120.0, None), ("tetrahedron", 180.0, None)]
    cases += [("octahedron", 60.0, None), ("octahedron", -60.0, None)]
    for polyhedron, turn, pivot in cases:
        env = BeastTurnEnv(turn_deg=turn, polyhedron=polyhedron)
        policy = SharpTurn(env.observation_space, env.action_space, pivot=pivot, max_tumbles=6)
        runs = [run_episode(env, policy, s, 8000) for s in seeds]
        out[f"{polyhedron} {turn} {pivot}"] = runs
        print(
            f"turn ({polyhedron}, turn_deg {turn}, pivot {pivot}): heading change "
            f"{_summary([r['heading_change_deg'] for r in runs])} deg, error "
            f"{_summary([r['heading_error_deg'] for r in runs])} deg, tumbles "
            f"{_summary([len(r['history']) for r in runs])}, sequences {sorted({' '.join(r['history']) for r in runs})}",
            flush=True,
        )
    return out


def bench_recover(seeds):
    from baselines.beast import Righting
    from polyenvs.beast.tasks import BeastRecoverEnv

    env = BeastRecoverEnv()
    policy = Righting(env.observation_space, env.action_space)
    runs = [run_episode(env, policy, s, 2000, until_done=False) for s in seeds]
    ok = [r for r in runs if r["success"] == 1.0]
    print(f"recover: {len(ok)}/{len(runs)} reached a stance", end="")
    print(f"; time to stance {_summary([r['time_to_stance_s'] for r in ok])} s" if ok else "")
    return runs


def bench_faults(seeds):
    from baselines.beast import RollingGait
    from polyenvs.beast.tasks import BeastRollEnv

    out = {}
    for limb in range(1, 7):
        env = BeastRollEnv(polyhedron="octahedron", disabled_limbs=(limb,))
        policy = RollingGait(env.observation_space, env.action_space, disabled_limbs=(limb,))
        for start in ("task", "on top"):
            if start == "on top" and limb - 1 not in _task_support(env):
                continue  # the task's start already has the limb on top
            options = None if start == "task" else {"qpos": _stance_without(env, limb)}
            runs = [run_episode(env, policy, s, 6000, until_done=False, reset_options=options) for s in seeds]
            out[f"{limb} {start}"] = runs
            print(
                f"6-beast, limb {limb} disabled, start {start}, 60 s: along heading "
                f"{_summary([r['distance_m'] for r in runs])} m, displacement "
                f"{_summary([r['displacement_m'] for r in runs])} m, tumbles {_summary([len(r['history']) for r in runs])}",
                flush=True,
            )
    return out


def floor_touches(env) -> set:
    """Names of the robot's geoms other than feet touching the floor now (body, links)."""
    import mujoco

    m, d = env.unwrapped.model, env.unwrapped.data
    floor = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "floor")
    out = set()
    for c in d.contact[: d.ncon]:
        if floor in (c.geom1, c.geom2):
            other = mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_GEOM, c.geom2 if c.geom1 == floor else c.geom1)
            if not other.endswith("_foot"):
                out.add(other)
    return out


def bench_crawl(seeds):
    from baselines.beast import Crawl
    from baselines.beast.crawl import crawl_stance_qpos
    from polyenvs.beast.tasks import BeastRollEnv

    out = {}
    for limb in range(1, 7):
        env = BeastRollEnv(polyhedron="octahedron", disabled_limbs=(limb,))
        policy = Crawl(env.observation_space, env.action_space, disabled_limbs=(limb,))
        for start in ("on top", "task"):
            # From the crawl stance, 60 s; from the task's rolling stance (reorientation first), 120 s, with the
            # distance at 60 s as well.
            options = {"qpos": crawl_stance_qpos(limb)} if start == "on top" else None
            max_steps = 6000 if start == "on top" else 12000
            runs = []
            for s in seeds:
                touched: set = set()
                at60: dict = {}

                def on_step(e, info, t=touched, a=at60):
                    t.update(floor_touches(e))
                    if e.unwrapped._elapsed == 6000:
                        a["distance_m"] = e.unwrapped.episode_metrics()["distance_m"]
                        a["displacement_m"] = float(np.linalg.norm(e.unwrapped.data.qpos[:2]))

                r = run_episode(env, policy, s, max_steps, until_done=False, reset_options=options, on_step=on_step)
                controller = list(policy._controllers.values())[-1]  # this episode's
                crawl = getattr(controller, "crawl", None) or controller
                r["crawl_steps"] = getattr(crawl, "steps", 0)
                r["reoriented_s"] = getattr(controller, "reoriented_at", 0.0 if start == "on top" else None)
                r["failure"] = getattr(controller, "failure", None)
                r["at60"] = at60
                r["floor_touches"] = sorted(touched)
                runs.append(r)
            out[f"{limb} {start}"] = runs
            reoriented = [r for r in runs if r["reoriented_s"] is not None]
            line = (
                f"6-beast crawl, limb {limb} disabled, start {start}: reoriented {len(reoriented)}/{len(runs)}"
                + (
                    f" in {_summary([r['reoriented_s'] for r in reoriented])} s"
                    if start == "task" and reoriented
                    else ""
                )
                + f"; {max_steps // 100} s: along heading {_summary([r['distance_m'] for r in runs])} m, displacement "
                f"{_summary([r['displacement_m'] for r in runs])} m, steps {_summary([r['crawl_steps'] for r in runs])}"
            )
            if start == "task":
                line += (
                    f"; at 60 s: along heading {_summary([r['at60'].get('distance_m', np.nan) for r in runs])} m, "
                    f"displacement {_summary([r['at60'].get('displacement_m', np.nan) for r in runs])} m"
                )
                fails = sorted({r["failure"] for r in runs if r["failure"]})
                if fails:
                    line += f"; not reoriented: {fails}"
            line += (
                f"; non-foot floor contacts {sorted({g for r in runs for g in r['floor_touches']}) or 'none'}; "
                f"sim_unstable {sum(r['sim_unstable'] for r in runs)}/{len(runs)}"
            )
            print(line, flush=True)
    return out


def _task_support(env) -> set:
    from polyenvs.beast import model as M

    return set(M.stance_orientation(env.unwrapped.polyhedron)[1].tolist())


def _stance_without(env, limb: int) -> np.ndarray:
    """The gait's nominal stance on a support face without ``limb`` (1-based) and without its opposite, so the
    broken limb points up (the paper's reorientation), first tumble along world +x."""
    import itertools

    from baselines.beast.planner import TUCKED, BeastPlanner

    planner = BeastPlanner("octahedron")
    dirs = planner.dirs
    up_limb = limb - 1
    for face in itertools.combinations(range(6), 3):
        if up_limb in face or any(dirs[i] @ dirs[j] < -0.99 for i, j in itertools.combinations(face, 2)):
            continue
        if float(dirs[list(face)].sum(axis=0) @ dirs[up_limb]) < 0:  # the broken limb on the upper side
            break
    q = np.tile(TUCKED, (6, 1))
    for i, angles in planner.stance_angles(face).items():
        q[i] = angles
    a, b, c = sorted(face)
    l1, l2, l3 = planner.order_edge(planner.feet(q.ravel()), a, b, c)
    rot = planner.stance_orientation(l1, l2, l3)  # body -> frame with x along the first tumble, z up
    quat = np.zeros(4)
    import mujoco

    mujoco.mju_mat2Quat(quat, rot.ravel())
    return np.concatenate([[0.0, 0.0, planner.config.stance_height], quat, q.ravel()])


BENCHES = {
    "tumble": bench_tumble,
    "roll": bench_roll,
    "roll6": bench_roll6,
    "turn": bench_turn,
    "recover": bench_recover,
    "faults": bench_faults,
    "crawl": bench_crawl,
}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=10, help="seeds 0 .. N-1 per measurement (default 10)")
    parser.add_argument("--only", default=",".join(BENCHES), help="comma-separated subset of " + ", ".join(BENCHES))
    parser.add_argument("--json", default=None, help="write every run's metrics to this file")
    args = parser.parse_args(argv)
    names = [n for n in args.only.split(",") if n]
    unknown = sorted(set(names) - set(BENCHES))
    if unknown or args.seeds < 1:
        parser.error(f"unknown measurement(s) {unknown}" if unknown else "--seeds must be >= 1")
    seeds = list(range(args.seeds))
    results = {}
    for name in names:
        t0 = time.perf_counter()
        results[name] = BENCHES[name](seeds)
        print(f"  ({name}: {time.perf_counter() - t0:.1f} s wall)", flush=True)
        sys.stdout.flush()
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=1, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
