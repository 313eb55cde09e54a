"""A restart for an effect that is a share of a force a state-space family carries in its
own compiled form (an asymmetric yield on Spencer, an asymmetric damping or yield on the
tanh family: :attr:`~hystdisc.models.families.base.SystemFamily.scaled_effects`).

A state-space family has no stage-1 structure, so the loop refits it plus such an effect
from its own optimum with the share at 0 or at its one-step estimate. A strong asymmetry
bends that optimum beyond the refit's reach: a Spencer damper whose yield is 0.4 alpha
in tension and 1.6 alpha in compression was fitted without it at 50 times the noise, with
``alpha`` at 0 and ``A`` at its bound, and the refit from there wanted ``r_y = -1e13``; a
tanh damper with ``r_c = -0.35`` ended its refit at 13 times the noise with the yield
velocity at 0. :func:`share_restart` gives the loop (:data:`~hystdisc.closing.rounds.Restart`)
a start that does not rely on that optimum: the family's start term family (its
``start_base``) refitted with the effect from its stage-1 start, as the loop refits a term
family, and the state-space family fitted from every start mapped from that fit, the
share carried (:func:`~hystdisc.fitting.multistart.system_fit`).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from hystdisc.closing.refit import refit_with, stage1_start
from hystdisc.closing.rounds import Restart
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OEFit
from hystdisc.fitting.multistart import system_fit
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import EFFECTS


def share_restart(
    data: FitData,
    eq,
    base_fit: Callable[[str], OEFit | None],
    shape: Callable[[OEFit], object],
    max_nfev: int,
    say: Callable[[str], None] = lambda msg: None,
    mapper: Callable | None = None,
) -> Restart:
    """The loop's restart for an effect whose share a state-space family's force carries.

    Parameters
    ----------
    data : FitData
        The output-error data of the discovery.
    eq : EqData or None
        Its equation-error data (the term family's stage-1 start); None: no restart.
    base_fit : callable
        ``base_fit(name)``: the term family ``name`` fitted without effects (the table's
        fit, or one made for this), None when there is none.
    shape : callable
        ``shape(fit)``: the stage-1 shape constants of a fit's family (the start of its
        shape search).
    max_nfev : int
        Iterations of each fit.
    say : callable
        Progress messages.
    mapper : callable, optional
        ``map``-like runner of the state-space family's starts (threads).

    Returns
    -------
    callable
        ``restart(effect, values, par)``: for an effect in ``par.family.scaled_effects``,
        ``values`` with the family's parameters and the effect's share replaced by those
        of the state-space family fitted from the term family's optimum with the effect;
        None for other effects, without stage-1 data, or when a fit fails. One restart
        per family and effect, one ``base_fit`` per start family.
    """
    made: dict[tuple[str, str], dict | None] = {}
    bases: dict[str, OEFit | None] = {}  # one start family's fit for every share

    def restart(effect: str, values: dict, par) -> dict | None:
        fam = par.family
        if eq is None or not fam.is_system or effect not in fam.scaled_effects:
            return None
        memo = (fam.name, effect)
        if memo not in made:
            try:
                with np.errstate(all="ignore"):
                    made[memo] = _restarted(fam, effect)
            except (HystdiscError, np.linalg.LinAlgError, ValueError, FloatingPointError):
                made[memo] = None  # no restart: the loop keeps its own refit
        own = made[memo]
        return None if own is None else {**values, **own}

    def _restarted(fam, effect: str) -> dict | None:
        if fam.start_base not in bases:
            bases[fam.start_base] = base_fit(fam.start_base)
        base = bases[fam.start_base]
        if base is None:
            return None
        say(f"closing the loop: {fam.name} restarted from {fam.start_base} with {effect}")
        effects = (*base.par.effects, effect)
        start = stage1_start(eq, base, effects, data, s0=shape(base))
        with_effect = refit_with(data, base, effect, None, max_nfev, False, start)
        fit = system_fit(fam.name, with_effect, data, max_nfev, mapper=mapper, say=say)
        keep = {*fam.param_names(), *EFFECTS[effect].shares}
        return {k: float(v) for k, v in fit.params.items() if k in keep}

    return restart


def first_of(*restarts: Restart | None) -> Restart:
    """One restart that asks each of ``restarts`` in turn (None ones skipped) and gives
    the first start one of them makes.

    Examples
    --------
    >>> never = lambda effect, values, par: None
    >>> shift = lambda effect, values, par: {**values, "theta_off": 0.1} if effect == "offset" else None
    >>> both = first_of(never, None, shift)
    >>> both("offset", {"k_s": 1.0}, None), both("coulomb", {}, None)
    ({'k_s': 1.0, 'theta_off': 0.1}, None)
    """
    given = [r for r in restarts if r is not None]

    def restart(effect: str, values: dict, par) -> dict | None:
        for r in given:
            found = r(effect, values, par)
            if found is not None:
                return found
        return None

    return restart
