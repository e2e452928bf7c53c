"""Held-out layouts: the ``layouts`` keyword every environment takes, and how a family splits its layouts into a
training distribution and a disjoint held-out one (as Procgen's ``distribution_mode`` and MiniGrid's levels separate
training from evaluation).

``layouts`` is one of :data:`LAYOUTS`:

- ``"default"``: the environment's own layout distribution, bit for bit what it was before the keyword existed;
- ``"train"``: a randomised distribution, drawn from the environment's seeded generator at every reset;
- ``"test"``: a held-out distribution, also seeded, that contains neither the default layout nor any training one.

A family declares its split once, as a :class:`LayoutSplit`: one or more :class:`SplitParameter` (a layout
parameter with a training interval and a disjoint test interval, their unit and the reason for them). A training
layout has every split parameter in its training interval, a test layout every one in its test interval, so the two
cannot share a layout; :meth:`LayoutSplit.classify` says which side a drawn layout is on (each environment reports its
episode's values through ``episode_layout()``), which is how the tests check the split. The docstring's Arguments row
comes from the declaration (:meth:`LayoutSplit.argument_row`, filled in by :func:`documents_layouts`).

Beside its split a family declares the kinds of feature its layouts hold (:class:`LayoutKind`: a pillar, a 45° wall,
an obstacle in the way) and a function that finds them in a drawn layout, so that the tests can check that the
training side draws every kind the test side does (a held-out layout should be new in its split parameter, not in
what an agent meets there) and the layouts guide can show them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from polyenvs.core import libm
from polyenvs.core.parameters import fill_placeholder
from polyenvs.core.validation import check_choice

__all__ = [
    "DIAGONAL_WALL",
    "LAYOUTS",
    "SLANTED_WALL",
    "LayoutKind",
    "LayoutSplit",
    "SplitParameter",
    "check_layouts",
    "documents_layouts",
    "wall_direction_kinds",
]

#: The values of every environment's ``layouts`` keyword.
LAYOUTS = ("default", "train", "test")


def check_layouts(value) -> str:
    """``value`` if it is one of :data:`LAYOUTS`, else ``ValueError`` naming ``layouts``."""
    return check_choice("layouts", value, LAYOUTS)


@dataclass(frozen=True)
class SplitParameter:
    """A layout parameter whose training and test values come from disjoint closed intervals.

    Attributes:
        name: what it measures (``"room width"``), as the docstring and the error messages say it.
        unit: its unit (``"cm"``, ``""``).
        train, test: ``(low, high)`` intervals; they must not overlap.
    """

    name: str
    unit: str
    train: tuple[float, float]
    test: tuple[float, float]

    def __post_init__(self):
        for side in (self.train, self.test):
            if not side[0] <= side[1]:
                raise ValueError(f"{self.name}: interval {side} is empty")
        if not (self.train[1] < self.test[0] or self.test[1] < self.train[0]):
            raise ValueError(f"{self.name}: the train {self.train} and test {self.test} intervals overlap")

    def interval(self, layouts: str) -> tuple[float, float]:
        """The interval of ``layouts`` ("train" or "test")."""
        return self.train if layouts == "train" else self.test

    def draw(self, rng: np.random.Generator, layouts: str, size: int | None = None):
        """Uniform value(s) in the interval of ``layouts``, from ``rng``."""
        low, high = self.interval(layouts)
        return low + (high - low) * (rng.random() if size is None else rng.random(size))

    def side(self, values) -> str | None:
        """ "train" or "test" if every one of ``values`` lies in that interval, else ``None``."""
        values = np.atleast_1d(np.asarray(values, dtype=np.float64))
        for layouts, (low, high) in (("train", self.train), ("test", self.test)):
            if values.size and ((values >= low) & (values <= high)).all():
                return layouts
        return None

    def describe(self, layouts: str) -> str:
        low, high = self.interval(layouts)
        unit = f" {self.unit}" if self.unit else ""
        return f"{self.name} in [{low:g}, {high:g}]{unit}"


@dataclass(frozen=True)
class LayoutSplit:
    """A family's split of its layouts into training and held-out test distributions.

    Attributes:
        parameters: the split parameters; a layout is "train" (or "test") when every one lies in its train (test)
            interval.
        varies: what else a "train" or "test" layout draws, in words, for the docstring.
        held_out: what "test" adds beyond the test intervals (hand-drawn plans, for instance), in words.
    """

    parameters: tuple[SplitParameter, ...]
    varies: str
    held_out: str = ""

    def classify(self, values: dict) -> str | None:
        """The side ("train", "test", or ``None`` for neither) of a layout given as ``{parameter name: value(s)}``
        (what an environment's ``episode_layout()`` returns)."""
        sides = {p.side(values[p.name]) for p in self.parameters}
        return sides.pop() if len(sides) == 1 else None

    def argument_row(self) -> str:
        """The ``layouts`` row of an environment docstring's Arguments table (argument, default, meaning)."""
        train = ", ".join(p.describe("train") for p in self.parameters)
        test = ", ".join(p.describe("test") for p in self.parameters)
        held_out = f"; {self.held_out}" if self.held_out else ""
        return (
            f'| layouts | "default" | "default": the layout described above; "train": {self.varies}, drawn at each '
            f'reset, {train}; "test" (held out, disjoint from "train" and from "default"): the same with {test}'
            f"{held_out} (:mod:`polyenvs.core.layouts`) |"
        )


@dataclass(frozen=True)
class LayoutKind:
    """A kind of feature that a family's layouts hold.

    Attributes:
        name: what the guide and the tests call it (``"pillar"``).
        meaning: how its family's kind finder tells it in a drawn layout, in words.
    """

    name: str
    meaning: str


#: Wall directions (*ours*) within this many degrees of a multiple of 45° count as that multiple: a layout's
#: coordinates rounded to 1 mm turn a 20 cm cut by up to 0.3°.
ANGLE_TOLERANCE_DEG = 1.0
DIAGONAL_WALL = LayoutKind("45° wall", "a wall at 45° to the room's axes (a cut corner, an octagon's side)")
SLANTED_WALL = LayoutKind("slanted wall", "a wall at an angle that is no multiple of 45° (a trapezoid's side)")


def wall_direction_kinds(segments) -> set[str]:
    """The kinds that the directions of ``segments`` ``(S, 4)`` hold: :data:`DIAGONAL_WALL`, :data:`SLANTED_WALL`."""
    seg = np.asarray(segments, dtype=np.float64)
    degrees = np.degrees(libm.arctan2(seg[:, 3] - seg[:, 1], seg[:, 2] - seg[:, 0])) % 90.0
    from_multiple = np.minimum(degrees % 45.0, 45.0 - degrees % 45.0)
    kinds = set()
    if (np.abs(degrees - 45.0) <= ANGLE_TOLERANCE_DEG).any():
        kinds.add(DIAGONAL_WALL.name)
    if (from_multiple > ANGLE_TOLERANCE_DEG).any():
        kinds.add(SLANTED_WALL.name)
    return kinds


def documents_layouts(split: LayoutSplit):
    """Class decorator: put ``split``'s :meth:`~LayoutSplit.argument_row` where the docstring says ``{layouts}``
    (with that line's indentation), and keep ``split`` as the class's ``layout_split``."""

    def decorate(cls):
        cls.__doc__ = fill_placeholder(cls.__doc__, "{layouts}", split.argument_row())
        cls.layout_split = split
        return cls

    return decorate
