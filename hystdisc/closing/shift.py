"""A restart for an effect that is a shift of the measured angle (the offset).

The offset's torque ``k_s (theta - theta_off)`` is the family's own spring on the angle
shifted by ``theta_off``. A refit of the model plus the offset starts from the optimum
the missing offset distorted; it can end in a basin that fits the data it saw at the
noise and predicts the held-out runs at three times the noise. :func:`shift_restart`
gives the loop (:data:`~hystdisc.closing.loop.Restart`) another start that does not
rely on that optimum: the family fitted again, with every start it has (stage 1, the
related families' optima, the current levels), on the data shifted by the refit's
``theta_off``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from hystdisc.data import Dataset
from hystdisc.fitting import FamilyParametrization, OEFit
from hystdisc.models import EFFECTS


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


def shift_restart(
    dataset: Dataset,
    fit_family: Callable[[Dataset, str], OEFit | None],
    say: Callable[[str], None] = lambda msg: None,
    min_shift: float = 0.0,
) -> Callable[[str, dict, FamilyParametrization], dict | None]:
    """The loop's restart for the shift effects (an effect's
    :attr:`~hystdisc.models.effects.Effect.shift_param`: the parameter that is the shift).

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

    Returns
    -------
    callable
        ``restart(effect, values, par)`` (:data:`~hystdisc.closing.loop.Restart`): for a
        shift effect, ``values`` with the family's own replaced by its fit on the data
        shifted by the effect's value (rescaled to torque units when ``par`` has z in
        them: :meth:`~hystdisc.models.Family.in_torque_units`). None for other
        effects, a shift not above ``min_shift`` or not finite, a failed fit, or a fit
        in torque units for a model in z_sat units. One fit per family and shift
        (rounded to 4 digits).
    """
    made: dict[tuple[str, float], OEFit | None] = {}

    def restart(effect: str, values: dict, par: FamilyParametrization) -> dict | None:
        key = EFFECTS[effect].shift_param or None
        shift = float(values.get(key, np.nan)) if key is not None else np.nan
        if not (np.isfinite(shift) and abs(shift) > min_shift):
            return None
        name = par.family.name
        memo = (name, float(f"{shift:.4g}"))
        if memo not in made:
            say(
                f"closing the loop: {name} fitted again on the angle shifted by {key} = {shift:.4g}"
            )
            made[memo] = fit_family(shifted(dataset, shift), name)
        fit = made[memo]
        if fit is None:
            return None
        own = dict(fit.params)
        norm = getattr(par, "norm", None)
        if getattr(fit.par, "norm", None) != norm:
            if norm != "alpha_1":
                return None  # a loop that never saturates has no z_sat to rescale to
            own = par.family.in_torque_units(own)  # the model's z is in torque units
        return {**values, **own, key: shift}

    return restart
