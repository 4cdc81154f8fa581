"""Tabulated profiles: ``R_d(r)`` given as samples, the paper's user-defined diffusion profiles (CSV files)."""

import csv
import itertools
from pathlib import Path

import numpy as np

from ..errors import ConvsssError
from .base import CHANNELS, Profile

#: The most data rows a profile file may have (a plot or a render slows with every row; 10 000 resolve any profile
#: to well below its noise).
MAX_PROFILE_ROWS = 100_000
#: The largest radius a tabulated profile may reach, in mm (a kilometre: no medium diffuses light farther; 1e300
#: overflowed the energy integrals and the plots).
MAX_RADIUS_MM = 1e6

class TabulatedProfile(Profile):
    """A profile given as samples ``R_d(r_k)`` per channel: the paper's user-defined diffusion profiles.

    Between samples the profile is interpolated in log space by a monotone cubic (PCHIP on ``log R_d``), so it stays
    smooth, positive and non-increasing; from the last positive sample to a following zero sample it falls linearly
    to zero. Before the first radius it is constant, past the last radius it is zero (``support``).

    Parameters
    ----------
    r_mm : array_like, shape (n,)
        Radii in mm: finite, >= 0, strictly increasing, n >= 2.
    values : array_like, shape (n, 3) or (n,)
        ``R_d`` in 1/mm^2: finite, >= 0, non-increasing with r in every channel, positive at the first radius.
    """

    def __init__(self, r_mm, values, name="tabulated"):
        from scipy.interpolate import PchipInterpolator

        r = np.asarray(r_mm, dtype=np.float64)
        v = np.asarray(values, dtype=np.float64)
        if v.ndim == 1:
            v = np.repeat(v[:, None], 3, axis=1)
        self.name = name
        self._check(r, v)
        self.r, self.values = r, v
        self.support = float(r[-1])
        self._curves = []
        for c in range(3):
            positive = v[:, c] > 0
            n_pos = int(positive.sum())
            log_curve = PchipInterpolator(r[:n_pos], np.log(v[:n_pos, c])) if n_pos >= 2 else None
            self._curves.append((n_pos, log_curve))
        self._build_energy_table()

    @staticmethod
    def _check(r, v):
        if r.ndim != 1 or len(r) < 2:
            raise ConvsssError(f"tabulated profile needs at least 2 radii in a 1-D list, got shape {r.shape}")
        if v.shape != (len(r), 3):
            raise ConvsssError(f"tabulated profile values have shape {v.shape}: expected ({len(r)}, 3) or ({len(r)},)")
        bad = ~np.isfinite(r) | (r < 0) | (r > MAX_RADIUS_MM)
        if bad.any():
            raise ConvsssError(f"tabulated profile radius r={float(r[bad][0])!r} is not allowed: "
                               f"radii are in mm, finite, from 0 to {MAX_RADIUS_MM:g}")
        step = np.diff(r)
        if np.any(step <= 0):
            k = int(np.argmax(step <= 0))
            raise ConvsssError(f"tabulated profile radii must strictly increase: r={float(r[k])!r} "
                               f"is followed by {float(r[k + 1])!r}")
        for c in range(3):
            col = v[:, c]
            bad = ~np.isfinite(col) | (col < 0)
            if bad.any():
                k = int(np.argmax(bad))
                raise ConvsssError(f"tabulated profile value {float(col[k])!r} at r={float(r[k])!r} mm, "
                                   f"channel {CHANNELS[c]}, is not allowed: values must be finite and >= 0")
            rise = np.diff(col) > 0
            if rise.any():
                k = int(np.argmax(rise))
                raise ConvsssError(f"tabulated profile increases in channel {CHANNELS[c]} from {float(col[k])!r} "
                                   f"at r={float(r[k])!r} mm to {float(col[k + 1])!r} at r={float(r[k + 1])!r} mm: "
                                   "a diffusion profile must not increase with r")
            if col[0] <= 0:
                raise ConvsssError(f"tabulated profile is zero at its first radius in channel {CHANNELS[c]}: "
                                   "R_d must be positive at the smallest radius")

    @classmethod
    def from_csv(cls, path):
        """Read a CSV with a header and the columns ``r_mm, R, G, B`` (one row per radius).

        Parameters
        ----------
        path : str or Path
            A text file: the header ``r_mm,R,G,B``, then at least 2 rows of 4 numbers (more columns are ignored).

        Returns
        -------
        TabulatedProfile

        Raises
        ------
        ConvsssError
            In one line, when the file is missing, not a text CSV, has a row of fewer than 4 columns, a value that
            is not a number, or fewer than 2 rows of data (and for every check of the profile itself).
        """
        path = Path(path)
        if not path.is_file():
            raise ConvsssError(f"profile file {str(path)!r} does not exist")
        try:
            with path.open(newline="", encoding="utf-8") as f:
                rows = [row for row in itertools.islice(csv.reader(f), MAX_PROFILE_ROWS + 2) if row]
            if len(rows) > MAX_PROFILE_ROWS + 1:
                raise ConvsssError(f"profile file {str(path)!r} has more than {MAX_PROFILE_ROWS} rows: a radial "
                                   "profile needs a few thousand (resample it, e.g. every 1 % in r)")
        except (UnicodeDecodeError, csv.Error) as e:
            raise ConvsssError(f"profile file {str(path)!r} is not a CSV (text with the columns r_mm, R, G, B): "
                               f"{' '.join(str(e).split())}") from None
        for k, row in enumerate(rows):
            if len(row) < 4:
                raise ConvsssError(f"profile file {str(path)!r} line {k + 1} has {len(row)} columns: "
                                   "a profile needs 4 columns r_mm, R, G, B")
        header = [h.strip().lower() for h in rows[0]] if rows else []
        if header[:4] != ["r_mm", "r", "g", "b"]:
            got = rows[0] if rows else "nothing"
            raise ConvsssError(f"profile file {str(path)!r} must start with the header 'r_mm,R,G,B', got {got}")
        try:
            table = np.array([[float(x) for x in row[:4]] for row in rows[1:]], dtype=np.float64).reshape(-1, 4)
        except ValueError as e:
            raise ConvsssError(f"profile file {str(path)!r} has a value that is not a number: {e}") from None
        if table.shape[0] < 2:
            raise ConvsssError(f"profile file {str(path)!r} needs at least 2 rows of data")
        return cls(table[:, 0], table[:, 1:4], name=path.name)

    def __repr__(self):
        return f"TabulatedProfile({self.name!r}, {len(self.r)} radii up to {self.support} mm)"

    def __call__(self, r):
        r = np.clip(np.asarray(r, dtype=np.float64), self.r[0], None)
        out = np.zeros(r.shape + (3,))
        for c, (n_pos, log_curve) in enumerate(self._curves):
            r_last = self.r[n_pos - 1]
            inside = r <= r_last
            if log_curve is not None:
                out[..., c] = np.where(inside, np.exp(log_curve(np.minimum(r, r_last))), 0.0)
            else:
                out[..., c] = np.where(inside, self.values[0, c], 0.0)
            if n_pos < len(self.r):  # linear fall to the first zero sample
                r_zero = self.r[n_pos]
                ramp = (r > r_last) & (r < r_zero)
                out[..., c] += np.where(ramp, self.values[n_pos - 1, c] * (r_zero - r) / (r_zero - r_last), 0.0)
        return out

    def _build_energy_table(self, per_interval=64):
        """Cumulative ``∫ 2 pi r R_d dr`` on a fine grid (``per_interval`` points between samples, plus [0, r_0])."""
        edges = np.concatenate([[0.0], self.r]) if self.r[0] > 0 else self.r
        t = np.linspace(0.0, 1.0, per_interval + 1)[:-1]
        grid = np.concatenate([a + (b - a) * t for a, b in zip(edges[:-1], edges[1:])] + [[edges[-1]]])
        integrand = 2.0 * np.pi * grid[:, None] * self(grid)
        steps = 0.5 * (integrand[1:] + integrand[:-1]) * np.diff(grid)[:, None]
        self._energy_r = grid
        self._energy = np.concatenate([np.zeros((1, 3)), np.cumsum(steps, axis=0)])

    def energy_within(self, radius):
        radius = np.asarray(radius, dtype=np.float64)
        return np.stack([np.interp(radius, self._energy_r, self._energy[:, c]) for c in range(3)], axis=-1)

    @property
    def total_reflectance(self):
        return self._energy[-1].copy()
