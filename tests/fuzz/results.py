"""A small valid ``results.json`` and the edits the fuzz tests make to it."""

from __future__ import annotations

from hypothesis import strategies as st

BASE_RESULTS = {
    "version": "0.1.0",
    "input": "data.csv",
    "experiment": "release",
    "noise_std": 0.001,
    "terms": {"torque": ["theta_dot", "z", "i*z"], "hysteresis": ["theta_dot", "|theta_dot|*z"]},
    "family": "dahl",
    "families": {
        "dahl": {
            "parameters": {"k_x": {"value": 0.8, "ci95": [0.79, 0.81]}},
            "rms": 0.001,
            "bic": -1000.0,
            "n_params": 5,
            "term_model": {
                "torque": {"theta": 158.0, "theta_dot": 0.8, "z": 0.5, "i*z": 1.5},
                "hysteresis": {"theta_dot": 20.0, "|theta_dot|*z": -20.0},
                "n": 1.0,
                "J": 1.0,
            },
        },
        "bingham": {
            "parameters": {},
            "rms": 0.002,
            "bic": -900.0,
            "n_params": 5,
            "term_model": {
                "torque": {
                    "theta": 158.0,
                    "theta_dot": 0.8,
                    "i*theta_dot": 0.6,
                    "sign(theta_dot)": 0.3,
                },
                "hysteresis": {},
                "n": 1.0,
                "J": 1.0,
            },
        },
    },
    "model": {
        "torque": {"theta": 158.0, "theta_dot": 0.8, "z": 0.5, "i*z": 1.5},
        "hysteresis": {"theta_dot": 20.0, "|theta_dot|*z": -20.0},
        "n": 1.0,
        "J": 1.0,
    },
    "effects": [],
    "unexplained": False,
    "residual": {"rms": 0.001},
}

JSON_VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(10**30), 10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.sampled_from(
        ["nan", "inf", "-1e999", "1e5", "", "z", "theta_dot", "|theta_dot|*z", "release", "driven"]
    )
    | st.text(max_size=6),
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(
            st.sampled_from(["torque", "hysteresis", "n", "J", "z", "theta", "x"]),
            inner,
            max_size=3,
        )
    ),
    max_leaves=5,
)
JSON_PATHS = st.lists(
    st.sampled_from(
        [
            "families",
            "dahl",
            "bingham",
            "term_model",
            "model",
            "torque",
            "hysteresis",
            "n",
            "J",
            "z",
            "theta",
            "experiment",
            "|theta_dot|*z",
            "family",
        ]
    ),
    min_size=1,
    max_size=4,
)


def mutate_json(doc, path, value, delete):
    cur = doc
    for key in path[:-1]:
        if not isinstance(cur, dict) or key not in cur:
            return
        cur = cur[key]
    if not isinstance(cur, dict):
        return
    if delete:
        cur.pop(path[-1], None)
    else:
        cur[path[-1]] = value
