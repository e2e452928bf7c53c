"""Episodes must not pass through numpy's float64 transcendental ufuncs: numpy picks their kernels from the CPU (SVML
or its own AVX-512 code on an AVX-512 machine, the C library elsewhere), and these differ in the last bit, so the same
seed gave another Buckybot episode on another machine (WallFollow, ``wall_follower_rules``, seed 1039: return 330.696
with AVX-512, 329.218 with AVX2). Families and their baselines use :mod:`polyenvs.core.libm` (``math``, the C
library) or compiled numba code (which calls the C library) instead; this scan refuses the ufuncs anywhere else in
those modules. Rendering is exempt: no observation, reward or metric reads a frame."""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from polyenvs.core import libm

ROOT = Path(__file__).resolve().parents[1]
_MODULES = sorted(
    path
    for pattern in (
        "polyenvs/core/*.py",
        "polyenvs/buckybot/*.py",
        "polyenvs/bumper/*.py",
        "polyenvs/swarm/*.py",
        "baselines/buckybot.py",
        "baselines/bumper.py",
        "baselines/swarm.py",
    )  # fmt: skip
    for path in ROOT.glob(pattern)
    if path.name != "rendering.py"
)

#: numpy ufuncs whose float64 loop is dispatched by CPU feature (numpy 2.4: loops_umath_fp, loops_exponent_log,
#: loops_hyperbolic, loops_trigonometric), and their aliases.
_DISPATCHED = {
    "sin", "cos", "tan", "arcsin", "arccos", "arctan", "arctan2", "asin", "acos", "atan", "atan2",
    "sinh", "cosh", "tanh", "arcsinh", "arccosh", "arctanh", "asinh", "acosh", "atanh",
    "exp", "exp2", "expm1", "log", "log2", "log10", "log1p", "logaddexp", "logaddexp2", "cbrt", "power", "pow",
    "float_power",
}  # fmt: skip

#: ``(module, function, ufunc)`` uses that stay, each with its reason.
_ALLOWED = {
    # The bearing is a float32 observation, so numpy computes in float32 (its own Cody-Waite kernel, the same
    # on AVX2 and AVX-512); libm would widen it to float64 and change these baselines' episodes.
    ("baselines/swarm.py", "goal_force", "cos"),
    ("baselines/swarm.py", "goal_force", "sin"),
    ("baselines/swarm.py", "extra_force", "cos"),
    ("baselines/swarm.py", "extra_force", "sin"),
}


def _is_compiled(function: ast.FunctionDef) -> bool:
    for decorator in function.decorator_list:
        target = decorator.func if isinstance(decorator, ast.Call) else decorator
        name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
        if name in ("njit", "jit"):
            return True
    return False


def _dispatched_uses(tree: ast.AST, function: str = "<module>"):
    """``(function, ufunc, line)`` of each ``np.<dispatched ufunc>`` outside compiled functions."""
    for node in ast.iter_child_nodes(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            if not _is_compiled(node):
                yield from _dispatched_uses(node, node.name)
            continue
        if (
            isinstance(node, ast.Attribute)
            and isinstance(node.value, ast.Name)
            and node.value.id in ("np", "numpy")
            and node.attr in _DISPATCHED
        ):
            yield function, node.attr, node.lineno
        yield from _dispatched_uses(node, function)


def test_the_scan_covers_every_family_module():
    names = {path.relative_to(ROOT).as_posix() for path in _MODULES}
    assert {"polyenvs/buckybot/simulator.py", "polyenvs/buckybot/geometry.py", "baselines/buckybot.py"} <= names
    assert not any(name.endswith("rendering.py") for name in names)


@pytest.mark.parametrize("path", _MODULES, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_no_cpu_dispatched_float64_ufuncs_in_episode_code(path):
    module = path.relative_to(ROOT).as_posix()
    uses = _dispatched_uses(ast.parse(path.read_text(), filename=module))
    refused = [f"{module}:{line} np.{ufunc} in {function}" for function, ufunc, line in uses
               if (module, function, ufunc) not in _ALLOWED]  # fmt: skip
    assert not refused, "use polyenvs.core.libm (the C library) instead: " + "; ".join(refused)


def test_the_scan_sees_a_planted_use():
    tree = ast.parse("import numpy as np\nX = np.cos(1.0)\ndef f(a):\n    return np.arctan2(a, 1.0)\n")
    assert [(f, u) for f, u, _ in _dispatched_uses(tree)] == [("<module>", "cos"), ("f", "arctan2")]
    compiled = ast.parse("@njit(cache=True)\ndef f(a):\n    return np.cos(a)\n")
    assert list(_dispatched_uses(compiled)) == []


def test_libm_functions_equal_the_c_library_element_by_element():
    import math

    rng = np.random.default_rng(0)
    x, y = rng.uniform(-10.0, 10.0, (2, 4, 3))
    assert np.array_equal(libm.cos(x), [[math.cos(v) for v in row] for row in x])
    pairs = zip(y.ravel(), x.ravel(), strict=True)
    assert np.array_equal(libm.arctan2(y, x).ravel(), [math.atan2(a, b) for a, b in pairs])
    assert libm.arcsin(1.0 / 3.0) == math.asin(1.0 / 3.0) and isinstance(libm.sin(0.5), np.float64)
    # float32 stays float32 (numpy's promotion), through the C library's atan2f; sine and cosine have no such twin.
    bearing = libm.arctan2(np.float32(0.3), np.float32(-0.5))
    assert isinstance(bearing, np.float32) and libm.arctan2(np.float32(0.3), 2.0).dtype == np.float32
    with pytest.raises(TypeError, match="float64"):
        libm.cos(np.float32(1.0))
