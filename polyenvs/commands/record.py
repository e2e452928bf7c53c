"""``polyenvs record``: a GIF or MP4 of one episode of a policy (needs ``polyenvs[render]``)."""

from __future__ import annotations

import argparse
from pathlib import Path

from polyenvs.commands.flags import CliError, check_output_file, float_flag, int_flag, parse_json_object
from polyenvs.core.extras import install_hint
from polyenvs.limits import MAX_FRAMES, MAX_SEED, MAX_STEPS
from polyenvs.registry import bare_id

__all__ = ["MAX_FPS", "MIN_FPS", "RECORD_FORMATS", "add_parser", "run"]

#: Output formats of ``polyenvs record``: suffix -> what writing it needs.
RECORD_FORMATS = {".gif": "imageio", ".mp4": "imageio-ffmpeg"}
#: ``polyenvs record --fps`` bounds: a GIF frame lasts at most 655.35 s (a 16-bit count of 10 ms), and no player
#: shows more than a few hundred frames a second.
MIN_FPS, MAX_FPS = 0.01, 1000.0


def add_parser(subparsers) -> argparse.ArgumentParser:
    p = subparsers.add_parser("record", help="record a GIF or MP4 of a policy (needs polyenvs[render])")
    p.add_argument(
        "env_id", help="a Gymnasium id (polyenvs/BuckybotGoal-v0) or a PettingZoo module (polyenvs.swarm.corridor_v0)"
    )
    p.add_argument("--policy", default="paper", help="a baseline's name, 'paper' (default), or a trained model's path")
    p.add_argument("--policy-kwargs", default="{}", help="JSON object of baseline parameters")
    p.add_argument("--seed", default="0", help=f"episode seed, 0 to {MAX_SEED} (default 0)")
    p.add_argument("--max-steps", default="300", help=f"at most this many steps, 1 to {MAX_STEPS} (default 300)")
    p.add_argument(
        "--every",
        default="1",
        help=f"keep one frame every this many steps, >= 1 (default 1: all); at most {MAX_FRAMES} frames in all",
    )
    p.add_argument(
        "--fps",
        default=None,
        help=f"frames per second, {MIN_FPS:g} to {MAX_FPS:g} (default: the env's render_fps / --every)",
    )
    p.add_argument("--env-kwargs", default="{}", help="JSON object of environment keyword arguments")
    p.add_argument("--output", default="episode.gif", help="a .gif, or a .mp4 (needs imageio-ffmpeg)")
    p.set_defaults(func=run)
    return p


def run(args: argparse.Namespace) -> int:
    from polyenvs.evaluation.episodes import make_agent, make_env
    from polyenvs.evaluation.rollout import episode_frames

    seed = int_flag("--seed", args.seed, 0, MAX_SEED)
    max_steps = int_flag("--max-steps", args.max_steps, 1, MAX_STEPS)
    every = int_flag("--every", args.every, 1, MAX_STEPS)
    fps = float_flag("--fps", args.fps, MIN_FPS, MAX_FPS)
    frames = max_steps // every + 2  # the first, one every `every` steps, the last
    if frames > MAX_FRAMES:
        raise CliError(
            f"--max-steps {max_steps} with --every {every} keeps up to {frames} frames in memory, more than "
            f"{MAX_FRAMES}: raise --every to {-(-max_steps // (MAX_FRAMES - 2))} or lower --max-steps"
        )
    output = Path(args.output)
    iio = _video_writer(output)
    check_output_file(output, "--output")
    env_kwargs = parse_json_object(args.env_kwargs, "--env-kwargs")
    policy_kwargs = parse_json_object(args.policy_kwargs, "--policy-kwargs")

    env = make_env(args.env_id, env_kwargs, render_mode="rgb_array")
    try:
        env_id = bare_id(args.env_id)
        policy = make_agent(args.policy, env_id, env, seed=seed, policy_kwargs=policy_kwargs)
        frames = episode_frames(env, policy, seed, max_steps, every=every)
        fps = fps or min(max(env.metadata.get("render_fps", 10) / every, MIN_FPS), MAX_FPS)
    finally:
        env.close()
    _write_video(iio, output, frames, fps)
    print(f"wrote {len(frames)} frames to {output}")
    return 0


def _video_writer(output: Path):
    """imageio's writer (``imageio.v3``) for ``output``, once its format and what writing it needs are checked."""
    suffix = output.suffix.lower()
    if suffix not in RECORD_FORMATS:
        raise CliError(f"--output {output}: the file name must end in {' or '.join(RECORD_FORMATS)}")
    try:
        import imageio.v3 as iio
    except ImportError:
        raise CliError(f"recording needs imageio: {install_hint('render')}") from None
    if suffix == ".mp4":
        try:
            import imageio_ffmpeg

            imageio_ffmpeg.get_ffmpeg_exe()
        except (ImportError, RuntimeError):
            raise CliError(f"--output {output}: writing .mp4 needs imageio-ffmpeg: {install_hint('render')}") from None
    return iio


def _write_video(iio, output: Path, frames: list, fps: float) -> None:
    """Write ``frames`` to ``output`` (a .gif or an .mp4) at ``fps``, atomically."""
    import numpy as np

    from polyenvs.files import atomic_path

    suffix = output.suffix.lower()
    video = np.stack(frames)
    if suffix == ".gif":
        options = {"duration": 1000 / fps, "loop": 0}
    else:  # H.264 in yuv420p needs even sides: repeat the last row / column where needed
        video = np.pad(video, ((0, 0), (0, video.shape[1] % 2), (0, video.shape[2] % 2), (0, 0)), mode="edge")
        options = {"fps": fps, "macro_block_size": 1}
    try:
        with atomic_path(output, keep_suffix=True) as tmp:
            iio.imwrite(tmp, video, extension=suffix, **options)
            if tmp.stat().st_size == 0:  # ffmpeg can fail without an exception
                raise OSError("the writer produced an empty file")
    except OSError as exc:
        raise CliError(f"--output {output}: could not write it: {exc}") from None
