"""One idiom for physical parameters: each is declared once, as a field of a frozen dataclass, with its default,
plausible range, unit and source; the validation and the documentation's table are made from that declaration.

```python
@documented
@dataclass(frozen=True)
class CartModel:
    '''The cart.

    {parameters}
    '''

    backup_cm: float = parameter(6.0, 1.0, 30.0, "cm", "ours: 35 ticks")

    def __post_init__(self):
        check_parameters(self)
```

:func:`check_parameters` refuses a value outside its range (or a bool, a string, NaN) with ``ValueError`` naming the
field, as :func:`polyenvs.core.validation.check_in_range` does; :func:`parameter_table` writes the Markdown table a
docstring's Arguments section shows; :func:`parameter_ranges` gives ``{name: (low, high)}`` to code that draws or
sweeps parameters. An environment takes its family's parameters as ``**physical`` keywords of its constructor, each
named once, in the dataclass (its ``params_class``: a task that changes a default or narrows a range subclasses the
dataclass and sets its own), and builds the dataclass from them with :func:`physical_parameters`:

```python
params_class = CartModel

def __init__(self, *, render_mode=None, **physical):
    self.model = physical_parameters(type(self), self.params_class, physical)
```
"""

from __future__ import annotations

import dataclasses
from typing import TypeVar

from polyenvs.core.validation import check_in_range

__all__ = [
    "argument_rows",
    "check_parameters",
    "documented",
    "documents_arguments",
    "fill_placeholder",
    "SharedVersionHistory",
    "parameter",
    "parameter_ranges",
    "parameter_table",
    "physical_parameters",
]

#: A family's parameter dataclass.
P = TypeVar("P")


def parameter(default: float, low: float, high: float, unit: str = "", source: str = "ours") -> dataclasses.Field:
    """A dataclass field for a physical parameter: ``default`` in ``[low, high]`` (``unit``), from ``source``."""
    if not low <= default <= high:
        raise ValueError(f"default {default!r} is outside its own range [{low:g}, {high:g}]")
    return dataclasses.field(default=default, metadata={"range": (low, high), "unit": unit, "source": source})


def _declared(cls_or_instance) -> list[dataclasses.Field]:
    return [f for f in dataclasses.fields(cls_or_instance) if "range" in f.metadata]


def check_parameters(instance) -> None:
    """Check every declared parameter of a (frozen) dataclass instance and store it as a ``float``."""
    for f in _declared(instance):
        low, high = f.metadata["range"]
        object.__setattr__(instance, f.name, check_in_range(f.name, getattr(instance, f.name), low, high))


def parameter_ranges(cls) -> dict[str, tuple[float, float]]:
    """``{name: (low, high)}`` of every declared parameter, in declaration order."""
    return {f.name: f.metadata["range"] for f in _declared(cls)}


def physical_parameters(owner: type, params_class: type[P], physical: dict) -> P:
    """``params_class(**physical)``, for an environment whose constructor takes ``params_class``'s parameters as
    ``**physical``: each keyword must be a declared parameter (the others keep their defaults). Any other keyword
    raises ``TypeError`` in Python's own wording for ``owner``'s constructor (``X.__init__() got an unexpected
    keyword argument 'name'``), which tools probe for (TorchRL's ``GymEnv`` tries ``frameskip=``); a bad value raises
    ``ValueError`` naming its parameter (:func:`check_parameters`)."""
    unknown = sorted(set(physical) - set(parameter_ranges(params_class)))
    if unknown:
        raise TypeError(f"{owner.__name__}.__init__() got an unexpected keyword argument {unknown[0]!r}")
    return params_class(**physical)


def parameter_table(cls) -> str:
    """The Markdown table of every declared parameter: name, default, range, unit, source."""
    rows = ["| parameter | default | range | unit | source |", "| --- | --- | --- | --- | --- |"]
    for f in _declared(cls):
        low, high = f.metadata["range"]
        rows.append(
            f"| {f.name} | {f.default:g} | [{low:g}, {high:g}] | {f.metadata['unit']} | {f.metadata['source']} |"
        )
    return "\n".join(rows)


def fill_placeholder(doc: str, placeholder: str, text: str) -> str:
    """``doc`` with ``text`` at ``placeholder``, its later lines indented as the placeholder's line is."""
    at = doc.index(placeholder)
    indent = doc[doc.rindex("\n", 0, at) + 1 : at]
    return doc.replace(placeholder, text.replace("\n", "\n" + indent))


def documented(cls):
    """Class decorator (outside ``@dataclass``): put :func:`parameter_table` where the docstring says ``{parameters}``."""
    cls.__doc__ = fill_placeholder(cls.__doc__, "{parameters}", parameter_table(cls))
    return cls


def documents_arguments(parameters_cls):
    """Class decorator for an environment whose constructor takes ``parameters_cls``'s fields as keywords: put
    :func:`argument_rows` where its docstring's Arguments table says ``{arguments}``."""

    def decorate(cls):
        cls.__doc__ = fill_placeholder(cls.__doc__, "{arguments}", argument_rows(parameters_cls, indent=""))
        return cls

    return decorate


def argument_rows(cls, indent: str = "    ") -> str:
    """Rows ``| name | default | source, in [low, high] unit |`` of every declared parameter, for an environment
    docstring's Arguments table (columns argument, default, meaning)."""
    rows = []
    for f in _declared(cls):
        low, high = f.metadata["range"]
        unit = f" {f.metadata['unit']}" if f.metadata["unit"] else ""
        rows.append(f"{indent}| {f.name} | {f.default:g} | {f.metadata['source']}, in [{low:g}, {high:g}]{unit} |")
    return "\n".join(rows)


class SharedVersionHistory:
    """Mixin of a family base whose tasks share a Version History: a subclass's docstring gets the base's
    ``version_history`` where it says ``{version_history}``."""

    version_history: str = ""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        if cls.__doc__ and "{version_history}" in cls.__doc__:
            cls.__doc__ = fill_placeholder(cls.__doc__, "{version_history}", cls.version_history)
