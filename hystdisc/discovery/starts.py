"""From stage 1 to stage 2: a family's equation-error start, the name of a structure."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from hystdisc.discovery.data import EqData
from hystdisc.discovery.varpro import coef_dict, grid_minima, varpro
from hystdisc.models import HYSTERESIS_TERM_NAMES, TermModel
from hystdisc.models.shapes import FAMILY_SHAPE, SHAPES
from hystdisc.registry import get_family, term_family_names


def family_start(
    eq: EqData,
    family: str,
    extra_terms: Sequence[str] = (),
    s0: np.ndarray | None = None,
    one_level: bool = False,
    constant: bool = True,
) -> tuple[dict[str, float], dict[str, float]]:
    """Stage-1 (equation-error) start of a family's output-error fit.

    The shape constants of the family's hysteresis shape and the coefficients of its
    torque terms (with the spring ``theta`` and ``extra_terms``, e.g. an effect's) are
    found by variable projection and mapped to the family's parameters, clipped inside
    their bounds. Discovery starts every family's fit from it; the closing loop starts the
    augmented structures from it.

    Parameters
    ----------
    eq : EqData
        Equation-error data.
    family : str
        Family name.
    extra_terms : sequence of str
        Torque terms added to the family's (the ones it already has are ignored).
    s0 : ndarray, optional
        Shape constants to start the local search from (skips the grid).
    one_level : bool
        All runs share one current: the ``i*`` terms are left out.
    constant : bool
        Add a constant column when the motion is not imposed (release and forced
        experiments: keeps an offset in the data from corrupting the start: z, integrated
        from 0, would imitate it).

    Returns
    -------
    params : dict
        Family parameters, ``k_s`` and ``J``.
    coefs : dict
        The fitted torque coefficients by term.

    Examples
    --------
    A driven record of a Bingham damper at two currents:

    >>> t = np.linspace(0.0, 4.0, 801)
    >>> th, w = np.sin(3 * t), 3 * np.cos(3 * t)
    >>> runs = [(i, 0.5 * w + i * w + (0.2 + 0.1 * i) * np.tanh(w / 1e-3)) for i in (0.0, 1.0)]
    >>> eq = EqData("driven", [t, t], [th, th], [w, w], [0 * t, 0 * t], [T for _, T in runs],
    ...             np.array([0.0, 1.0]), [np.ones(t.size, dtype=bool)] * 2)
    >>> p, coefs = family_start(eq, "bingham")
    >>> sorted(p)
    ['J', 'c_a', 'c_b', 'f_a', 'f_b', 'k_s']
    >>> round(coefs["i*theta_dot"], 6), round(coefs["sign(theta_dot)"], 6)
    (1.0, 0.2)
    """
    fam = get_family(family)
    ft = [t for t in fam.torque_terms if not (one_level and t.startswith("i"))]
    lead = ["theta", "1"] if constant and not eq.experiment_type.motion_imposed else ["theta"]
    terms = [*lead, *ft]
    terms += [t for t in dict.fromkeys(extra_terms) if t not in terms]
    shape = FAMILY_SHAPE[fam.name]
    if s0 is not None and len(s0) != len(SHAPES[shape].shape_names):
        s0 = None
    s, c, _ = varpro(eq, shape, terms, s0=None if s0 is None else np.asarray(s0, dtype=float))
    coefs, J = coef_dict(eq, terms, c)
    b, n = SHAPES[shape].vector(s)
    hyst = {k: float(v) for k, v in zip(HYSTERESIS_TERM_NAMES, b, strict=True) if v != 0.0}
    with np.errstate(all="ignore"):
        p = fam.from_terms(TermModel(coefs, hyst, n, J))
    p["k_s"] = max(coefs.get("theta", 0.0), 0.0)
    p["J"] = J if J > 0 else 1.0
    # keep the start inside the physical bounds
    for spec in fam.params:
        v = p.get(spec.name, spec.default)
        if not np.isfinite(v):
            v = spec.default
        p[spec.name] = float(np.clip(v, spec.lower, spec.upper))
    return p, coefs


def family_starts(
    eq: EqData,
    family: str,
    basins: int = 2,
    s0: np.ndarray | None = None,
    one_level: bool = False,
    first: dict[str, float] | None = None,
) -> list[tuple[str, dict[str, float]]]:
    """Labelled stage-1 starts of a family's output-error fit: the start from the stage-1
    shape ``s0`` (:func:`family_start`; ``first`` when the caller already has it), then one from each of up to ``basins`` other
    basins of the shape's grid (:func:`~hystdisc.discovery.varpro.grid_minima`, at least 1
    apart from ``s0`` in the shape's coordinates).

    Examples
    --------
    >>> t = np.linspace(0.0, 4.0, 801)
    >>> th, w = np.sin(3 * t), 3 * np.cos(3 * t)
    >>> eq = EqData("driven", [t], [th], [w], [0 * t], [0.5 * np.tanh(5 * w)],
    ...             np.array([0.0]), [np.ones(t.size, dtype=bool)])
    >>> [label for label, _ in family_starts(eq, "dahl", basins=2, one_level=True)]
    ['stage 1', 'stage-1 basin 2', 'stage-1 basin 3']
    """
    if first is None:
        first, _ = family_start(eq, family, s0=s0, one_level=one_level)
    out = [("stage 1", dict(first))]
    if basins <= 0:
        return out
    fam = get_family(family)
    ft = [t for t in fam.torque_terms if not (one_level and t.startswith("i"))]
    shape = FAMILY_SHAPE[fam.name]
    if not SHAPES[shape].shape_names:  # no shape constants: one linear least squares
        return out
    # the columns family_start fits (the constant keeps an offset from ranking the grid)
    lead = ["theta"] if eq.experiment_type.motion_imposed else ["theta", "1"]
    pts = grid_minima(eq, shape, [*lead, *ft], basins + 1)
    # without s0 the first start came from the grid's best point
    ref = pts[0] if s0 is None and pts else np.asarray(s0, dtype=float)
    k = 1
    for g in pts:
        if g.size == ref.size and np.max(np.abs(g - ref)) < 1.0:
            continue
        if len(out) > basins:
            break
        k += 1
        p, _ = family_start(eq, family, s0=g, one_level=one_level)
        out.append((f"stage-1 basin {k}", p))
    return out


def describe_structure(torque: Sequence[str], shape: str) -> str:
    """Name a discovered structure after the family it matches (or 'modified Dahl').

    Examples
    --------
    >>> describe_structure(["theta", "theta_dot", "z", "i*z"], "dahl")
    'Dahl'
    >>> describe_structure(["theta_dot", "z"], "bouc-wen")
    "bouc-wen hysteresis with torque terms ['theta_dot', 'z']"
    """
    tset = {t for t in torque if t not in ("theta", "1")}
    for name in term_family_names():
        fam = get_family(name)
        if FAMILY_SHAPE[name] == shape and set(fam.torque_terms) == tset:
            return fam.title
    for name in term_family_names():  # a named variant of a family (the seed's own)
        fam = get_family(name)
        if FAMILY_SHAPE[name] == shape and frozenset(tset) in fam.variants:
            return fam.variants[frozenset(tset)]
    return f"{SHAPES[shape].name} hysteresis with torque terms {sorted(tset)}"
