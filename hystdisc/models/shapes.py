"""Hysteresis shapes: the hysteresis side of a stage-1 candidate, as the families declare it.

The hysteresis side of a model is nonlinear in a few *shape constants* (a rate, an
exponent). Each candidate shape is a small class: it names its hysteresis terms and its
shape constants and turns the constants into the coefficient vector of the hysteretic
rate, from which ``z(t)`` is integrated given the velocity record (see doc/design.rst,
section 3). :class:`HysteresisShape` owns the common work; a subclass per shape only says
what differs, pysindy-style.

Shape constants are handled in an unconstrained space: rates as ``log`` values, the
exponent as ``log n``.

Examples
--------
>>> SHAPES["dahl"].vector(np.log([20.0]))
(array([ 20., -20.,   0.,   0.,   0.]), 1.0)
>>> SHAPES["bouc-wen"].shape_dict(np.array([0.0, 0.5, 0.0]))
{'delta': 1.0, 'beta': 0.5, 'gamma': 0.5, 'n': 1.0}
>>> FAMILY_SHAPE["lugre"]
'dahl'
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from typing import ClassVar

import numpy as np

from hystdisc import registry
from hystdisc.models.terms import HYSTERESIS_TERM_NAMES

#: Exponents searched by discovery (smaller n makes the seed form Dahl-like and the state
#: non-Lipschitz at z = 0, which no fixed-step search should chase; fit Dahl instead).
N_RANGE = (0.25, 6.0)


class HysteresisShape:
    """A hysteresis-side candidate: its terms and the map shape constants -> rate coefficients.

    Subclasses set the class attributes and implement :meth:`coefficients`,
    :meth:`shape_dict` and, when they have shape constants, :meth:`grid` and
    :meth:`_clip_rest`.

    Attributes
    ----------
    name : str
        Name of the shape (the key of :data:`SHAPES`).
    terms : tuple of str
        Hysteresis terms of the rate, from :data:`hystdisc.models.HYSTERESIS_TERM_NAMES`.
    shape_names : tuple of str
        Names of the shape constants (in the unconstrained space).
    """

    name: ClassVar[str] = ""
    terms: ClassVar[tuple[str, ...]] = ()
    shape_names: ClassVar[tuple[str, ...]] = ()

    @property
    def has_state(self) -> bool:
        """The shape carries a hysteretic state ``z`` (it has hysteresis terms)."""
        return bool(self.terms)

    def coefficients(self, s: np.ndarray) -> tuple[tuple[float, ...], float]:
        """Coefficients of :attr:`terms` (in their order) and the exponent for ``s``."""
        return (), 1.0

    def vector(self, s: np.ndarray) -> tuple[np.ndarray, float]:
        """Rate coefficients (in ``HYSTERESIS_TERM_NAMES`` order) and exponent for ``s``."""
        b = np.zeros(len(HYSTERESIS_TERM_NAMES))
        coefs, n = self.coefficients(s)
        for term, c in zip(self.terms, coefs, strict=True):
            b[HYSTERESIS_TERM_NAMES.index(term)] = c
        return b, n

    def grid(self, scale: float) -> list[np.ndarray]:
        """Starting grid of shape constants for a displacement amplitude ``scale``."""
        return [np.zeros(0)]

    @staticmethod
    def _rates(scale: float) -> np.ndarray:
        """Log rates of the starting grid (0.3..300 per amplitude ``scale``)."""
        return np.log(np.geomspace(0.3, 300.0, 13) / max(scale, 1e-12))

    def clip(self, s: np.ndarray, scale: float) -> np.ndarray:
        """Keep shape constants in the searched box (rates 0.1..300 per amplitude ``scale``;
        beyond it z is a sign function, which the Bingham terms already cover)."""
        s = np.asarray(s, dtype=float).copy()
        if not self.shape_names:
            return s
        lo = np.log(0.1 / max(scale, 1e-12))
        s[0] = np.clip(s[0], lo, lo + np.log(3e3))
        self._clip_rest(s)
        return s

    def _clip_rest(self, s: np.ndarray) -> None:
        """Clip, in place, the shape constants after the rate."""

    def shape_dict(self, s: np.ndarray) -> dict[str, float]:
        """Shape constants in physical units (``rho`` or ``delta, beta, gamma, n``)."""
        return {}

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"


class NoShape(HysteresisShape):
    """No hysteretic state (Bingham): no terms, no shape constants."""

    name = "none"


class DahlShape(HysteresisShape):
    """Dahl-type rate ``rho * (theta_dot - |theta_dot| z)``; one constant, ``log rho``."""

    name = "dahl"
    terms = ("theta_dot", "|theta_dot|*z")
    shape_names = ("log_rho",)

    def coefficients(self, s: np.ndarray) -> tuple[tuple[float, ...], float]:
        rho = float(np.exp(s[0]))
        return (rho, -rho), 1.0

    def grid(self, scale: float) -> list[np.ndarray]:
        return [np.array([r]) for r in self._rates(scale)]

    def shape_dict(self, s: np.ndarray) -> dict[str, float]:
        return {"rho": float(np.exp(s[0]))}


class _BoucWenShape(HysteresisShape):
    """Bouc-Wen rate ``delta theta_dot - beta theta_dot |z|^n - gamma (third term)``.

    Constants ``log delta``, a split of ``delta`` into ``beta`` and ``gamma``
    (:meth:`split`), and ``log n``.
    """

    #: Values of the split in the starting grid.
    splits: ClassVar[tuple[float, ...]] = ()

    def split(self, v: float, delta: float) -> tuple[float, float]:
        """``beta, gamma`` from the split constant ``v`` and ``delta``."""
        raise NotImplementedError

    def coefficients(self, s: np.ndarray) -> tuple[tuple[float, ...], float]:
        d = self.shape_dict(s)
        return (d["delta"], -d["beta"], -d["gamma"]), d["n"]

    def grid(self, scale: float) -> list[np.ndarray]:
        out = []
        for r in self._rates(scale)[::2]:
            for v in self.splits:
                for n in (0.5, 1.0, 2.0):
                    out.append(np.array([r, v, np.log(n)]))
        return out

    def _clip_rest(self, s: np.ndarray) -> None:
        s[1] = self._clip_split(s[1])
        s[2] = np.clip(s[2], np.log(N_RANGE[0]), np.log(N_RANGE[1]))

    def _clip_split(self, v: float) -> float:
        raise NotImplementedError

    def shape_dict(self, s: np.ndarray) -> dict[str, float]:
        delta = float(np.exp(s[0]))
        beta, gamma = self.split(s[1], delta)
        return {
            "delta": delta,
            "beta": beta,
            "gamma": gamma,
            "n": float(np.clip(np.exp(s[2]), N_RANGE[0], N_RANGE[1])),
        }


class BoucWenShape(_BoucWenShape):
    """Seed-form Bouc-Wen: ``beta = phi * delta``, ``gamma = (1 - phi) * delta`` (``z_sat = 1``)."""

    name = "bouc-wen"
    terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^n")
    shape_names = ("log_delta", "phi", "log_n")
    splits = (-0.5, 0.0, 0.5, 0.9)

    def split(self, v: float, delta: float) -> tuple[float, float]:
        return float(v) * delta, (1.0 - float(v)) * delta

    def _clip_split(self, v: float) -> float:
        return np.clip(v, -3.0, 3.0)


class BoucWenStdShape(_BoucWenShape):
    """Standard-form Bouc-Wen: ``beta = delta cos(psi)``, ``gamma = delta sin(psi)``.

    The angle also covers loops that never saturate (``beta + gamma <= 0``, as in the
    Noel-Schoukens hysteretic benchmark).
    """

    name = "bouc-wen-std"
    terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^(n-1)")
    shape_names = ("log_delta", "psi", "log_n")
    # saturating at 0..120 deg and -30 deg, never saturating at 150, 170 and -70 deg
    splits = tuple(np.deg2rad((0.0, 45.0, 90.0, 120.0, -30.0, 150.0, 170.0, -70.0)))

    def split(self, v: float, delta: float) -> tuple[float, float]:
        return delta * float(np.cos(v)), delta * float(np.sin(v))

    def _clip_split(self, v: float) -> float:
        return np.angle(np.exp(1j * v))  # wrap to (-pi, pi]


#: The candidate shapes of stage 1, by name.
SHAPES: dict[str, HysteresisShape] = {
    sh.name: sh for sh in (NoShape(), DahlShape(), BoucWenShape(), BoucWenStdShape())
}
#: The shapes stage 1 compares by default (every one).
DEFAULT_SHAPES: tuple[str, ...] = tuple(SHAPES)


def shape_of(family) -> str:
    """Name of the shape whose hysteresis terms are those of ``family`` (a family object).

    LuGre shares Dahl's shape (on another z scale).
    """
    for name, sh in SHAPES.items():
        if sh.terms == tuple(family.hysteresis_terms):
            return name
    raise ValueError(f"no hysteresis shape has the terms of family '{family.name}'")


class _FamilyShapes(Mapping):
    """Family name -> its hysteresis shape, for the registered families in term form, in
    the registry's order (a live view: a family registered later is in it)."""

    def __getitem__(self, name: str) -> str:
        if name not in registry.term_family_names():
            raise KeyError(name)
        return shape_of(registry.get_family(name))

    def __iter__(self) -> Iterator[str]:
        return iter(registry.term_family_names())

    def __len__(self) -> int:
        return len(registry.term_family_names())


#: Hysteresis shape of each family in term form, in the registry's order.
FAMILY_SHAPE: Mapping[str, str] = _FamilyShapes()
