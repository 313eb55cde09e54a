"""A restart for an effect that changes the motion the model is driven by: a shift of the
measured angle (the offset) or a play between the measured motion and the damper (the
backlash).

The offset's torque ``k_s (theta - theta_off)`` is the family's own spring on the angle
shifted by ``theta_off``; a play of half-width ``r_b`` drives the family with the motion
the damper's end follows. A refit of the model plus such an effect starts from the
optimum the missing effect distorted; it can end in a basin that fits the data it saw at
the noise and predicts the held-out runs at three times the noise (an offset), or in one
that is not physical (a Spencer damper fitted without its 0.5 mm play: ``A = beta``,
``gamma = 0``; with the play refitted from there it diverges in a slow cycle).
:func:`motion_restart` gives the loop (:data:`~hystdisc.closing.loop.Restart`) another
start that does not rely on that optimum: the family fitted again, with every start it
has (stage 1, the related families' optima, the current levels), on the data shifted by
the refit's ``theta_off`` or seen through the play of the refit's ``r_b``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from hystdisc.data import Dataset
from hystdisc.fitting import FamilyParametrization, OEFit
from hystdisc.models import EFFECTS
from hystdisc.models.backlash import play_motion


def shifted(dataset: Dataset, shift: float) -> Dataset:
    """``dataset`` with every run's angle shifted: ``theta - shift``.

    Examples
    --------
    >>> import numpy as np
    >>> from hystdisc.data import Dataset, Run
    >>> ds = Dataset([Run("0", np.arange(3) * 0.01, [0.3, 0.2, 0.1], 0.0)], "release")
    >>> shifted(ds, 0.1).runs[0].theta.round(3).tolist()
    [0.2, 0.1, 0.0]
    """
    runs = [replace(r, theta=r.theta - shift) for r in dataset.runs]
    return replace(dataset, runs=runs)


def played(dataset: Dataset, r_b: float) -> Dataset:
    """``dataset`` with every run's motion seen through a play of half-width ``r_b``
    (:func:`~hystdisc.models.backlash.play_motion`; the velocity, measured or the
    motion's gradient, gives the side the gap starts closed on), and a measured velocity
    replaced by the play's.

    Examples
    --------
    >>> import numpy as np
    >>> from hystdisc.data import Dataset, Run
    >>> t = np.arange(6) * 0.1
    >>> ds = Dataset([Run("0", t, [0.0, 1.0, 2.0, 1.5, 0.5, -1.0], 0.0)], "driven")
    >>> played(ds, 0.5).runs[0].theta.tolist()
    [-0.5, 0.5, 1.5, 1.5, 1.0, -0.5]
    """
    runs = []
    for r in dataset.runs:
        v = r.theta_dot if r.theta_dot is not None else np.gradient(r.theta, r.t)
        theta, theta_dot = play_motion(r.theta, v, r_b)
        runs.append(replace(r, theta=theta, theta_dot=None if r.theta_dot is None else theta_dot))
    return replace(dataset, runs=runs)


def motion_restart(
    dataset: Dataset,
    fit_family: Callable[[Dataset, str], OEFit | None],
    say: Callable[[str], None] = lambda msg: None,
    min_shift: float = 0.0,
    min_play: float = 0.0,
) -> Callable[[str, dict, FamilyParametrization], dict | None]:
    """The loop's restart for the effects that change the motion: a shift (an effect's
    :attr:`~hystdisc.models.effects.Effect.shift_param`) or a play
    (:attr:`~hystdisc.models.effects.Effect.play_param`).

    Parameters
    ----------
    dataset : Dataset
        The data of the discovery.
    fit_family : callable
        ``fit_family(dataset, family)``: the family fitted with all its starts (no loop),
        or None when it fails.
    say : callable
        Progress messages.
    min_shift : float
        Smaller shifts are not restarted from (e.g. the noise of the angle: a base fit
        cannot be bent by an offset it cannot see).
    min_play : float
        Plays no wider than this are not restarted from (the noise of the measured motion).

    Returns
    -------
    callable
        ``restart(effect, values, par)`` (:data:`~hystdisc.closing.loop.Restart`): for a
        shift or a play effect, ``values`` with the family's own replaced by its fit on
        the data shifted by the effect's value or seen through its play (rescaled to
        torque units when ``par`` has z in them:
        :meth:`~hystdisc.models.Family.in_torque_units`). None for other effects, a
        value not finite or not above its floor (a play's must be positive), a failed
        fit, or a fit in torque units for a model in z_sat units. One fit per family,
        effect and value (rounded to 4 digits).
    """
    made: dict[tuple[str, str, float], OEFit | None] = {}

    def restart(effect: str, values: dict, par: FamilyParametrization) -> dict | None:
        eff = EFFECTS[effect]
        if eff.shift_param:
            key, floor, move, seen = eff.shift_param, min_shift, shifted, "the angle shifted by"
        elif eff.play_param:
            key, floor, move = eff.play_param, min_play, played
            seen = "the motion seen through a play of"
        else:
            return None
        value = float(values.get(key, np.nan))
        size = value if eff.play_param else abs(value)
        if not (np.isfinite(value) and size > floor):
            return None
        name = par.family.name
        memo = (name, key, float(f"{value:.4g}"))
        if memo not in made:
            say(f"closing the loop: {name} fitted again on {seen} {key} = {value:.4g}")
            made[memo] = fit_family(move(dataset, value), name)
        fit = made[memo]
        if fit is None:
            return None
        own = dict(fit.params)
        norm = getattr(par, "norm", None)
        if getattr(fit.par, "norm", None) != norm:
            if norm != "alpha_1":
                return None  # a loop that never saturates has no z_sat to rescale to
            own = par.family.in_torque_units(own)  # the model's z is in torque units
        return {**values, **own, key: value}

    return restart
