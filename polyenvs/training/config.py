"""Training configs in RL Zoo's format (``configs/<algo>.yml``), loaded without evaluating code.

One YAML mapping per file, keyed by environment id; each entry holds RL Zoo's keys::

    polyenvs/BuckybotWallFollow-v0:
      n_timesteps: !!float 1e6          # total steps (an integral number)
      policy: 'MlpPolicy'               # one of the algorithm's policy names
      n_envs: 8                         # parallel environments (default 1)
      normalize: true                   # VecNormalize: true/false, or "{'norm_obs': True, 'norm_reward': False}"
                                        #   (also "dict(norm_obs=True, ...)" or a YAML mapping); gamma follows the
                                        #   algorithm's gamma, as in RL Zoo
      env_wrapper: module.Wrapper       # per-env gym.Wrapper: an import path, a list of them, or a list of
                                        #   {path: {kwargs}} mappings (as RL Zoo)
      frame_stack: 4                    # VecFrameStack (optional)
      env_kwargs:                       # the environment's keyword arguments: a YAML mapping
        ctrl_cost_weight: 0.001
      policy_kwargs: "dict(net_arch=[64, 64], activation_fn=nn.Tanh)"
      learning_rate: lin_3e-4           # RL Zoo's linear schedule (also clip_range, clip_range_vf), or a number
      ...                               # every other key: a constructor argument of the algorithm

Every file reads the same here and in RL Zoo (``python -m rl_zoo3.train --conf-file``; tests/test_rl_zoo.py runs
it), so this reader takes exactly the forms RL Zoo takes: a Python-like string only where RL Zoo evaluates one
(``normalize``, ``policy_kwargs``, ``replay_buffer_kwargs``), a YAML mapping everywhere else (``env_kwargs``, a
wrapper's keyword arguments, other ``*_kwargs``: RL Zoo passes them on as they are). The strings are parsed from
their syntax tree: literals, lists, tuples, dicts, ``dict(...)`` and activation or optimizer classes by name
(``nn.Tanh``, ``th.nn.ReLU``, ``torch.optim.Adam``), nothing else. Every problem raises
:class:`~polyenvs.errors.InputError` with a one-line message naming the file, the id and the key.
"""

from __future__ import annotations

import ast
import difflib
import importlib
import inspect
import math
from dataclasses import dataclass, field
from numbers import Integral, Real
from pathlib import Path
from typing import Any

from polyenvs.core.extras import install_hint
from polyenvs.errors import InputError
from polyenvs.limits import MAX_N_ENVS, MAX_TIMESTEPS
from polyenvs.registry import bare_id

__all__ = [
    "META_KEYS",
    "TrainConfig",
    "config_dirs",
    "default_config_path",
    "jsonable",
    "load_config",
    "load_config_file",
    "parse_python_value",
]

#: RL Zoo's keys that are not constructor arguments of the algorithm.
META_KEYS = ("n_timesteps", "policy", "n_envs", "normalize", "env_wrapper", "frame_stack", "env_kwargs")
#: RL Zoo keys that polyenvs does not support, with the reason.
UNSUPPORTED_KEYS = {
    "callback": "training callbacks from the config are not supported by polyenvs train",
    "vec_env_wrapper": "VecEnv wrappers from the config are not supported by polyenvs train",
    "replay_buffer_class": "custom replay buffer classes are not supported by polyenvs train",
    "rollout_buffer_class": "custom rollout buffer classes are not supported by polyenvs train",
}
#: Constructor arguments that train() sets itself.
RESERVED_KEYS = {"self", "policy", "env", "tensorboard_log", "verbose", "seed", "device", "_init_setup_model"}
#: Keys RL Zoo turns into schedules ("lin_<value>": linear from value to 0 over training).
SCHEDULE_KEYS = ("learning_rate", "clip_range", "clip_range_vf")
#: Integer-defaulted arguments that take any number.
FLOAT_KEYS = {"max_grad_norm"}
#: The ``*_kwargs`` keys whose strings RL Zoo evaluates (ExperimentManager._preprocess_hyperparams); every other
#: one it passes to the algorithm as it is, so a string there would reach the constructor as a string.
EVALUATED_KWARGS = ("policy_kwargs", "replay_buffer_kwargs")

_MODULE_ALIASES = {"nn": "torch.nn", "th": "torch", "torch": "torch"}
#: Dotted names a config may use, by prefix: activation functions and optimizers.
_ALLOWED_NAME_PREFIXES = ("torch.nn.", "torch.optim.")


@dataclass
class TrainConfig:
    """One id's entry of a config file, checked and resolved for one algorithm."""

    path: Path
    env_id: str
    algo: str
    n_timesteps: int
    policy: str
    n_envs: int = 1
    normalize: bool = False
    normalize_kwargs: dict[str, Any] = field(default_factory=dict)
    #: Per-env wrappers: (import path, keyword arguments), applied in order.
    env_wrappers: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    frame_stack: int | None = None
    #: The environment's keyword arguments (RL Zoo's ``env_kwargs``), under the command line's own.
    env_kwargs: dict[str, Any] = field(default_factory=dict)
    #: Constructor arguments of the algorithm (schedules and classes resolved), without policy/env/seed.
    hyperparams: dict[str, Any] = field(default_factory=dict)
    #: The entry as written in the file.
    raw: dict[str, Any] = field(default_factory=dict)

    def wrapper_callables(self) -> list:
        """The ``env_wrapper`` classes bound to their keyword arguments (imports them)."""
        import functools

        return [
            functools.partial(_import_object(path, self._where("env_wrapper")), **kw) for path, kw in self.env_wrappers
        ]

    def resolved(self) -> dict[str, Any]:
        """Every setting as used, JSON-able: schedules as RL Zoo writes them, classes by dotted name."""
        doc: dict[str, Any] = {"policy": self.policy, "n_envs": self.n_envs, "n_timesteps": self.n_timesteps}
        # VecNormalize's arguments in full (never an empty, falsy dict), or false.
        doc["normalize"] = {"norm_obs": True, "norm_reward": True, **self.normalize_kwargs} if self.normalize else False
        if self.env_wrappers:
            doc["env_wrapper"] = [{path: kw} if kw else path for path, kw in self.env_wrappers]
        if self.frame_stack is not None:
            doc["frame_stack"] = self.frame_stack
        if self.env_kwargs:
            doc["env_kwargs"] = jsonable(self.env_kwargs)
        for key, value in self.hyperparams.items():
            raw = self.raw.get(key)
            doc[key] = raw if key in SCHEDULE_KEYS and isinstance(raw, str) else jsonable(value)
        return doc

    def _where(self, key: str) -> str:
        return f"{self.path}: {self.env_id}: {key}"


# ------------------------------------------------------------------------------------------------ file loading


def config_dirs() -> list[Path]:
    """Where the shipped configs are, in the order they are looked for: the package's own ``polyenvs/configs``
    (what a wheel installs: pyproject.toml maps the repository's top-level ``configs/`` there), then the
    ``configs/`` beside the package (a checkout, or an editable install of one)."""
    package = Path(__file__).resolve().parents[1]
    return [package / "configs", package.parent / "configs"]


def default_config_path(algo: str) -> Path:
    """The shipped ``<algo>.yml`` (see :func:`config_dirs`), wherever polyenvs runs from; InputError if none."""
    for directory in config_dirs():
        path = directory / f"{algo}.yml"
        if path.is_file():
            return path
    looked = " and ".join(str(d) for d in config_dirs())
    raise InputError(f"polyenvs ships no {algo}.yml config (looked in {looked}); give one with --config FILE")


def load_config_file(path: str | Path) -> dict[str, Any]:
    """The YAML mapping of a config file; a missing, unreadable or malformed file raises InputError."""
    try:
        import yaml
    except ImportError:  # pragma: no cover - pyyaml is in the train extra
        raise InputError(f"reading configs needs pyyaml: {install_hint('train')}") from None
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"config file {path} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"config file {path}: cannot read it: {exc}") from None
    try:
        document = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
        raise InputError(f"config file {path}: not valid YAML: {problem}{where}") from None
    if document is None:
        document = {}
    if not isinstance(document, dict):
        raise InputError(f"config file {path}: expected a mapping of environment ids, got {type(document).__name__}")
    return document


def load_config(path: str | Path, env_id: str, algo: str) -> TrainConfig:
    """Load ``env_id``'s entry of the config file ``path`` for ``algo`` (``"ppo"``, ``"dqn"``, ...), checked.

    Raises :class:`~polyenvs.errors.InputError` for a missing file or entry, an unknown key (with the nearest
    known one), a value of the wrong type, or a Python-like string outside the allowed syntax.
    """
    from baselines.algorithms import algo_class, get_algo

    get_algo(algo)
    path = Path(path)
    env_id = bare_id(env_id)
    document = load_config_file(path)
    if env_id not in document:
        known = ", ".join(str(k) for k in document) or "none"
        raise InputError(f"config file {path} has no entry for {env_id} (it has: {known})")
    entry = document[env_id]
    if not isinstance(entry, dict):
        raise InputError(f"{path}: {env_id}: expected a mapping of hyperparameters, got {entry!r}")
    for key in entry:
        if not isinstance(key, str):
            raise InputError(f"{path}: {env_id}: keys must be strings, got {key!r}")
    cls = algo_class(algo)
    return _resolve(path, env_id, algo, cls, dict(entry))


def _resolve(path: Path, env_id: str, algo: str, cls: type, entry: dict[str, Any]) -> TrainConfig:
    def where(key: str) -> str:
        return f"{path}: {env_id}: {key}"

    parameters = inspect.signature(cls.__init__).parameters
    _check_keys(entry, algo, cls, [k for k in parameters if k not in RESERVED_KEYS], where)
    if "n_timesteps" not in entry:
        raise InputError(f"{where('n_timesteps')}: missing (the number of training steps)")
    config = TrainConfig(
        path=path,
        env_id=env_id,
        algo=algo,
        n_timesteps=_count(entry["n_timesteps"], 1, where("n_timesteps"), MAX_TIMESTEPS),
        policy=_policy(entry.get("policy", "MlpPolicy"), cls, where("policy")),
        raw=entry,
    )
    _read_environment_keys(config, entry, where)
    hyperparams = {
        key: _algo_value(key, value, parameters[key].default, where(key))
        for key, value in entry.items()
        if key not in META_KEYS
    }
    config.hyperparams = hyperparams
    if "normalize" in entry:
        config.normalize, config.normalize_kwargs = _normalize(entry["normalize"], where("normalize"))
        if config.normalize and "gamma" in hyperparams:  # as RL Zoo: the return is discounted like the algorithm's
            config.normalize_kwargs["gamma"] = hyperparams["gamma"]
    return config


def _check_keys(entry: dict[str, Any], algo: str, cls: type, algo_keys: list[str], where) -> None:
    """Refuse a key that is not supported, or neither a key of ours (``META_KEYS``) nor an argument of ``cls``."""
    for key in entry:
        if key in UNSUPPORTED_KEYS:
            raise InputError(f"{where(key)}: {UNSUPPORTED_KEYS[key]}")
        if key not in META_KEYS and key not in algo_keys:
            close = difflib.get_close_matches(key, [*META_KEYS, *algo_keys], n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise InputError(f"{where(key)}: unknown key for {algo} ({cls.__name__}){hint}")


def _read_environment_keys(config: TrainConfig, entry: dict[str, Any], where) -> None:
    """The keys of ``entry`` that shape the training environments (copies, frames, wrappers, keywords), checked."""
    if "n_envs" in entry:
        config.n_envs = _count(entry["n_envs"], 1, where("n_envs"), MAX_N_ENVS)
    if "frame_stack" in entry:
        config.frame_stack = _count(entry["frame_stack"], 1, where("frame_stack"))
    if "env_wrapper" in entry:
        config.env_wrappers = _env_wrappers(entry["env_wrapper"], where("env_wrapper"))
    if "env_kwargs" in entry:
        config.env_kwargs = _env_kwargs(entry["env_kwargs"], where("env_kwargs"))


# ---------------------------------------------------------------------------------------------- value checks


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


def _yaml_hint(value: Any) -> str:
    """YAML 1.1 reads ``3e-4`` (no dot) as text: say how to write it."""
    if isinstance(value, str):
        try:
            float(value)
        except ValueError:
            return ""
        return " (YAML reads it as text: write it with a dot, 3.0e-4, or as !!float 3e-4)"
    return ""


def _mapping_only(value: Any, where: str, what: str) -> None:
    if isinstance(value, str):
        raise InputError(
            f"{where}: write {what} as a YAML mapping (one 'name: value' per indented line), not the string "
            f"{_show(value)}: RL Zoo passes it on as it is, without evaluating it"
        )


def _env_kwargs(value: Any, where: str) -> dict[str, Any]:
    """A YAML mapping, as RL Zoo needs it (it hands ``env_kwargs`` to ``gym.make`` as they are)."""
    _mapping_only(value, where, "env_kwargs")
    if not isinstance(value, dict) or not all(isinstance(k, str) for k in value):
        raise InputError(f"{where}: expected a mapping of keyword arguments, got {_show(value)}")
    return dict(value)


def _count(value: Any, minimum: int, where: str, maximum: int | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, Real):
        raise InputError(f"{where}: expected an integer >= {minimum}, got {_show(value)}{_yaml_hint(value)}")
    if not isinstance(value, Integral):
        if not math.isfinite(value) or value != int(value):
            raise InputError(f"{where}: expected an integer >= {minimum}, got {_show(value)}")
    value = int(value)
    if value < minimum:
        raise InputError(f"{where}: expected an integer >= {minimum}, got {value}")
    if maximum is not None and value > maximum:
        raise InputError(f"{where}: expected an integer <= {maximum}, got {value}")
    return value


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, Real) or not math.isfinite(value):
        raise InputError(f"{where}: expected a finite number, got {_show(value)}{_yaml_hint(value)}")
    return value


def _policy(value: Any, cls: type, where: str) -> str:
    aliases = getattr(cls, "policy_aliases", {})
    if not isinstance(value, str) or value not in aliases:
        raise InputError(f"{where}: expected one of {', '.join(aliases)} for {cls.__name__}, got {_show(value)}")
    return value


def _schedule(value: Any, where: str):
    from stable_baselines3.common.utils import LinearSchedule

    if isinstance(value, str):
        if value.startswith("lin_") and value.count("_") == 1:  # RL Zoo splits it at its one "_"
            try:
                start = float(value[4:])
            except ValueError:
                start = math.nan
            if math.isfinite(start):
                # RL Zoo's linear_schedule: progress_remaining * start, from start to 0 over training.
                return LinearSchedule(start, 0.0, 1.0)
        raise InputError(f"{where}: expected a number or 'lin_<number>' (a linear schedule), got {_show(value)}")
    return _number(value, where)


def _algo_value(key: str, value: Any, default: Any, where: str) -> Any:
    if key in SCHEDULE_KEYS:
        if value is None and default is None:
            return None
        return _schedule(value, where)
    if key.endswith("_kwargs"):
        return _kwargs_value(key, value, where)
    if key == "train_freq":
        return _train_freq(value, where)
    if isinstance(default, bool):
        if not isinstance(value, bool):
            raise InputError(f"{where}: expected true or false, got {_show(value)}")
        return value
    if isinstance(default, int) and key not in FLOAT_KEYS:
        return _count(value, -1 if default < 0 else 0, where)
    if isinstance(default, float) or key in FLOAT_KEYS:
        return float(_number(value, where))
    if isinstance(value, str) and _yaml_hint(value):
        raise InputError(f"{where}: got the text {value!r}{_yaml_hint(value)}")
    return value


def _kwargs_value(key: str, value: Any, where: str) -> dict | None:
    """A ``*_kwargs`` hyperparameter: a dict (or None), given as a mapping or, for ``EVALUATED_KWARGS``, as text."""
    if isinstance(value, str) and key in EVALUATED_KWARGS:
        value = parse_python_value(value, where)
    _mapping_only(value, where, key)
    if value is not None and not isinstance(value, dict):
        raise InputError(f"{where}: expected a dict, got {_show(value)}")
    return value


def _train_freq(value: Any, where: str) -> int | tuple[int, str]:
    """``train_freq``: a positive count of steps, or ``[n, "step" | "episode"]``."""
    if isinstance(value, list | tuple):
        if len(value) != 2 or value[1] not in ("step", "episode"):
            raise InputError(f"{where}: expected an integer or [n, 'step' | 'episode'], got {_show(value)}")
        return (_count(value[0], 1, where), value[1])
    return _count(value, 1, where)


def _normalize(value: Any, where: str) -> tuple[bool, dict[str, Any]]:
    if isinstance(value, bool):
        return value, {}
    if isinstance(value, str):
        value = parse_python_value(value, where)
    if not isinstance(value, dict):
        raise InputError(f"{where}: expected true, false or a dict of VecNormalize arguments, got {_show(value)}")
    from stable_baselines3.common.vec_env import VecNormalize

    allowed = [k for k in inspect.signature(VecNormalize.__init__).parameters if k not in ("self", "venv")]
    for key in value:
        if key not in allowed:
            raise InputError(f"{where}: unknown VecNormalize argument {key!r}; expected some of {', '.join(allowed)}")
    for key in ("norm_obs", "norm_reward", "training"):
        if key in value and not isinstance(value[key], bool):
            raise InputError(f"{where}: {key} must be True or False, got {_show(value[key])}")
    for key in ("clip_obs", "clip_reward", "gamma", "epsilon"):
        if key in value:
            value[key] = float(_number(value[key], f"{where}: {key}"))
    return True, dict(value)


def _env_wrappers(value: Any, where: str) -> list[tuple[str, dict[str, Any]]]:
    items = value if isinstance(value, list) else [value]
    wrappers = []
    for item in items:
        if isinstance(item, str):
            path, kwargs = item, {}
        elif isinstance(item, dict) and len(item) == 1:
            ((path, kwargs),) = item.items()
            _mapping_only(kwargs, where, f"the keyword arguments of {path}")
            if not isinstance(path, str) or not isinstance(kwargs, dict):
                raise InputError(f"{where}: expected {{'module.Wrapper': {{kwargs}}}}, got {_show(item)}")
        else:
            raise InputError(
                f"{where}: expected an import path 'module.Wrapper', a list of them, or "
                f"{{'module.Wrapper': {{kwargs}}}} mappings, got {_show(item)}"
            )
        if not callable(_import_object(path, where)):
            raise InputError(f"{where}: {path} is not a class or function")
        wrappers.append((path, dict(kwargs)))
    return wrappers


def _import_object(path: str, where: str) -> Any:
    module_name, _, name = path.rpartition(".")
    if not module_name:
        raise InputError(f"{where}: expected an import path 'module.Name', got {path!r}")
    try:
        return getattr(importlib.import_module(module_name), name)
    except (ImportError, AttributeError) as exc:
        raise InputError(f"{where}: cannot import {path}: {exc}") from None


# ---------------------------------------------------------------------------------- Python-like strings, safely


def parse_python_value(text: str, where: str = "value") -> Any:
    """Parse an RL Zoo Python-like string without evaluating code.

    Allowed: numbers, strings, True/False/None, unary minus, lists, tuples, dicts with string keys,
    ``dict(key=value, ...)``, and classes named ``nn.X``, ``th.nn.X``, ``torch.nn.X`` (an ``nn.Module`` class,
    such as an activation function) or ``th.optim.X`` / ``torch.optim.X`` (an optimizer class).
    """
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError as exc:
        raise InputError(f"{where}: not a Python expression: {exc.msg} (in {text!r})") from None
    return _literal(tree.body, where, text)


def _literal(node: ast.AST, where: str, text: str) -> Any:
    if isinstance(node, ast.Constant):
        if isinstance(node.value, bool | int | float | str) or node.value is None:
            return node.value
        raise _not_allowed(f"the constant {node.value!r}", where, text)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub | ast.UAdd):
        operand = _literal(node.operand, where, text)
        if isinstance(operand, bool) or not isinstance(operand, int | float):
            raise _not_allowed("a sign before a non-number", where, text)
        return -operand if isinstance(node.op, ast.USub) else operand
    if isinstance(node, ast.List):
        return [_literal(e, where, text) for e in node.elts]
    if isinstance(node, ast.Tuple):
        return tuple(_literal(e, where, text) for e in node.elts)
    if isinstance(node, ast.Dict):
        return _literal_dict(node, where, text)
    if isinstance(node, ast.Call):
        return _literal_dict_call(node, where, text)
    if isinstance(node, ast.Attribute | ast.Name):
        return _named_class(ast.unparse(node), where, text)
    raise _not_allowed(f"the expression {ast.unparse(node)!r}", where, text)


def _not_allowed(what: str, where: str, text: str) -> InputError:
    return InputError(f"{where}: {what} is not allowed (in {text!r})")


def _literal_dict(node: ast.Dict, where: str, text: str) -> dict:
    """``{"key": value, ...}``: string keys, no ``**`` unpacking."""
    out = {}
    for k, v in zip(node.keys, node.values, strict=True):
        if k is None:
            raise _not_allowed("'**' unpacking", where, text)
        key = _literal(k, where, text)
        if not isinstance(key, str):
            raise _not_allowed(f"the non-string key {key!r}", where, text)
        out[key] = _literal(v, where, text)
    return out


def _literal_dict_call(node: ast.Call, where: str, text: str) -> dict:
    """``dict(key=value, ...)``, the one call allowed."""
    if not (isinstance(node.func, ast.Name) and node.func.id == "dict") or node.args:
        raise _not_allowed(f"the call {ast.unparse(node.func)}(...) (only dict(key=value, ...))", where, text)
    out = {}
    for kw in node.keywords:
        if kw.arg is None:
            raise _not_allowed("'**' unpacking", where, text)
        out[kw.arg] = _literal(kw.value, where, text)
    return out


def _named_class(name: str, where: str, text: str) -> type:
    head, _, rest = name.partition(".")
    full = f"{_MODULE_ALIASES[head]}.{rest}" if head in _MODULE_ALIASES and rest else name
    if not full.startswith(_ALLOWED_NAME_PREFIXES) or full.count(".") != 2:
        raise InputError(
            f"{where}: the name {name!r} is not allowed (in {text!r}); names may only be torch classes such as "
            "nn.Tanh, nn.ReLU or th.optim.Adam"
        )
    import torch

    module_name, _, attr = full.rpartition(".")
    value = getattr(importlib.import_module(module_name), attr, None)
    base, base_name = (
        (torch.nn.Module, "torch.nn.Module")
        if module_name == "torch.nn"
        else (torch.optim.Optimizer, "torch.optim.Optimizer")
    )
    if not (isinstance(value, type) and issubclass(value, base)):
        raise InputError(f"{where}: {name} is not a {base_name} class (in {text!r})")
    return value


def jsonable(value: Any) -> Any:
    """``value`` with classes as dotted names (``torch.nn.Tanh``), tuples as lists, schedules by their repr."""
    if isinstance(value, type):
        for module in ("torch.nn", "torch.optim"):
            mod = importlib.import_module(module) if value.__module__.startswith(module) else None
            if mod is not None and getattr(mod, value.__name__, None) is value:
                return f"{module}.{value.__name__}"
        return f"{value.__module__}.{value.__qualname__}"
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if value is None or isinstance(value, bool | int | float | str):
        return value
    return repr(value)
