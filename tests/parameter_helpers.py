"""Helpers shared by the registry suites' checks of the physical parameters (``**physical``, each named once in its
family's dataclass, the environment's ``params_class``)."""

from __future__ import annotations

import contextlib
import re

import pytest

from polyenvs.core.parameters import parameter_ranges


def unknown_keyword_message(cls: type, name: str) -> str:
    """The pattern of Python's own ``TypeError`` for an unknown keyword of ``cls``'s constructor."""
    return rf"^{cls.__name__}\.__init__\(\) got an unexpected keyword argument {re.escape(repr(name))}"


def assert_physical_keywords_reach_their_fields(cls: type, make, monkeypatch) -> None:
    """``make(name=value)``, which builds a ``cls``, takes each of ``cls.params_class``'s parameters by name and
    builds the dataclass with that value and every other parameter as ``make()`` builds it (a task that intercepted a
    keyword and did not pass it on, or passed it to another field, fails here); a misspelled name raises Python's own
    ``TypeError``.

    The value is the end of the parameter's range away from its default. An end may clash with another parameter
    (the cart's narrowest bumper is narrower than its default wheels), which the dataclass or the task refuses with
    ``ValueError`` after the dataclass has been built: what it was built with is recorded first."""
    ranges = parameter_ranges(cls.params_class)
    built = []

    class Recording(cls.params_class):
        def __post_init__(self):
            built.append({name: getattr(self, name) for name in ranges})
            super().__post_init__()

    monkeypatch.setattr(cls, "params_class", Recording)
    make().close()
    (defaults,) = built  # the task's own defaults (the formation's arrival distance follows its spacing)
    for name, (low, high) in ranges.items():
        value = high if defaults[name] == low else low
        built.clear()
        with contextlib.suppress(ValueError):
            make(**{name: value}).close()
        assert built == [{**defaults, name: value}], name
    misspelled = next(iter(ranges))[:-1]
    with pytest.raises(TypeError, match=unknown_keyword_message(cls, misspelled)):
        make(**{misspelled: 1.0})
