"""Declared parameters: one definition per option (name, type, default, allowed values, help), checked in one place.

A transport declares its parameters as a tuple of :class:`Parameter`; so does the renderer. From the declarations
come the defaults, the one-line errors for bad values, the integrator's properties and the command line's options,
so none of them is written twice.
"""

import math
from dataclasses import dataclass

from .errors import ConvsssError


@dataclass(frozen=True)
class Parameter:
    """One parameter: ``kind`` is ``int``, ``float`` or ``str``.

    Numbers must lie in ``[low, high]`` (``(low, high]`` with ``low_open``); strings (and numbers, when given) must
    be one of ``choices``; a number may be ``inf`` only where ``infinite``. A ``None`` default makes the parameter
    optional. ``exposed = False`` marks a value the renderer sets itself (e.g. the pixel footprint), not a user option.
    A number parameter also takes each of its ``words`` (e.g. ``"auto"``), kept as the word, and a number written as
    text (``"inf"``, ``"2"``, ``"1e300"``: a scene file's ``<string>``), read as the number.
    """

    name: str
    kind: type
    default: object
    help: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    choices: tuple = ()
    exposed: bool = True
    infinite: bool = False
    words: tuple = ()

    def allowed(self):
        """What is allowed, in words (for errors and help).

        Examples
        --------
        >>> Parameter("layers", int, 8, "Layers.", low=2, high=256).allowed()
        'a whole number >= 2 and <= 256'
        >>> Parameter("layers", int, 8, "Layers.", low=2, high=256).check(1)
        Traceback (most recent call last):
        ...
        convsss.errors.ConvsssError: layers=1 is not allowed: it must be a whole number >= 2 and <= 256
        """
        if self.choices:
            return "one of " + ", ".join(_show(c) for c in self.choices)
        bounds = []
        if self.low is not None:
            bounds.append(f"> {_show(self.low)}" if self.low_open else f">= {_show(self.low)}")
        if self.high is not None:
            bounds.append(f"<= {_show(self.high)}")
        whole = "a whole number" if self.kind is int else "a number"
        named = ["inf"] * self.infinite + list(self.words)
        return whole + (" " + " and ".join(bounds) if bounds else "") + (", or " + " or ".join(named) if named else "")

    def check(self, value):
        """``value`` converted to ``kind`` if it is allowed; else a one-line :class:`ConvsssError`."""
        if value is None and self.default is None:
            return None
        bad = ConvsssError(f"{self.name}={value!r} is not allowed: it must be {self.allowed()}")
        if self.kind is str:
            if not isinstance(value, str) or (self.choices and value not in self.choices):
                raise bad
            return value
        if isinstance(value, str) and value.strip() in self.words:
            return value.strip()
        if isinstance(value, str):  # a number written as text: a scene file's <string>, a spec, load_dict
            try:
                value = float(value)
            except ValueError:
                raise bad from None
            value = int(value) if self.kind is int and value.is_integer() else value
        if isinstance(value, bool):
            raise bad
        try:
            converted = self.kind(value)
        except (TypeError, ValueError, OverflowError):
            raise bad from None
        if (self.kind is int and converted != value) or math.isnan(converted):
            raise bad
        if math.isinf(converted) and not (self.infinite and converted > 0):
            raise bad
        too_low = self.low is not None and (converted <= self.low if self.low_open else converted < self.low)
        too_high = self.high is not None and converted > self.high
        if too_low or too_high or (self.choices and converted not in self.choices):
            raise bad
        return converted


def _show(x):
    return f"{x:g}" if isinstance(x, float) else str(x)


def check_parameters(declared, given, owner):
    """``given`` (a mapping) checked against the ``declared`` parameters, with every default filled in.

    Raises a one-line :class:`ConvsssError` naming ``owner`` for a name it does not declare.
    """
    by_name = {p.name: p for p in declared}
    unknown = sorted(set(given) - set(by_name))
    if unknown:
        raise ConvsssError(f"{owner} has no parameter {unknown[0]!r}; its parameters are: "
                           f"{', '.join(by_name) or 'none'}")
    return {name: p.check(given[name]) if name in given else p.default for name, p in by_name.items()}
