"""The MATLAB .mat reader."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.io

from hystdisc.data import (
    load,
    read_mat,
)
from hystdisc.data.mat import _mat_needs_probe, _probe_loadmat
from hystdisc.errors import HystdiscError

from .helpers import (
    check_message,
    make_dataset,
)


def test_mat_round_trip_vectors(tmp_path):
    ds = make_dataset("driven", currents=(0.75,))
    r = ds[0]
    p = tmp_path / "run.mat"
    scipy.io.savemat(
        p, {"t": r.t[None, :], "theta": r.theta[:, None], "torque": r.torque, "current": 0.75}
    )
    back = read_mat(p)
    assert back.experiment == "driven" and back[0].current == 0.75
    assert np.array_equal(back[0].t, r.t) and np.array_equal(back[0].theta, r.theta)
    assert np.array_equal(back[0].torque, r.torque)
    assert np.array_equal(load(p)[0].theta, r.theta)


def test_mat_names_matrix_and_fs(tmp_path):
    rng = np.random.default_rng(3)
    n = 120
    angle = np.sin(np.arange(n) / 7.0) * 30.0
    p = tmp_path / "sas.mat"
    scipy.io.savemat(p, {"Angle": angle, "I": 0.5})
    ds = read_mat(p, columns={"theta": "angle", "current": "I"}, units={"theta": "deg"}, fs=1000.0)
    assert ds.experiment == "release" and ds[0].current == 0.5
    assert ds[0].theta == pytest.approx(np.radians(angle)) and ds[0].fs == pytest.approx(1000.0)
    m = np.column_stack([np.arange(n) * 1e-3, angle, rng.normal(size=n)])
    q = tmp_path / "matrix.mat"
    scipy.io.savemat(q, {"data": m.T})  # channels as rows: transposed automatically
    ds2 = read_mat(q, "forced", columns={"t": 0, "theta": 1, "input": 2}, current=0.0)
    assert np.array_equal(ds2[0].input, m[:, 2]) and ds2[0].n == n


def test_error_bad_mat_files(tmp_path):
    p = tmp_path / "junk.mat"
    p.write_bytes(b"this is not a mat file at all" * 10)
    with pytest.raises(HystdiscError) as exc:
        read_mat(p)
    check_message(exc, "junk.mat", "not a readable MATLAB")
    q = tmp_path / "novar.mat"
    scipy.io.savemat(q, {"angle": np.arange(50.0), "current": 0.1})
    with pytest.raises(HystdiscError) as exc:
        read_mat(q)
    check_message(exc, "novar.mat", "'theta' is missing", "angle")
    with pytest.raises(HystdiscError) as exc:
        read_mat(q, columns={"theta": "angle"})
    check_message(exc, "novar.mat", "no time variable", "fs")
    r = tmp_path / "nocur.mat"
    scipy.io.savemat(r, {"theta": np.sin(np.arange(50.0)), "t": np.arange(50.0)})
    with pytest.raises(HystdiscError) as exc:
        read_mat(r)
    check_message(exc, "nocur.mat", "run 0", "no coil current")


def _mat_file(path, compress: bool, **variables):
    scipy.io.savemat(path, variables, do_compression=compress)
    return path


def test_only_uncompressed_v5_files_are_probed_in_a_child(tmp_path):
    theta = np.sin(np.arange(50.0))
    plain = _mat_file(tmp_path / "plain.mat", False, theta=theta)
    packed = _mat_file(tmp_path / "packed.mat", True, theta=theta)
    v4 = tmp_path / "v4.mat"
    scipy.io.savemat(v4, {"theta": theta}, format="4")
    assert _mat_needs_probe(str(plain)) is True
    assert _mat_needs_probe(str(packed)) is False
    assert _mat_needs_probe(str(v4)) is False
    assert _probe_loadmat(str(plain)) is None  # a sound file: the child exits normally


def test_mat_index_maps_and_merged_files_errors(tmp_path):
    t = np.arange(60) * 1e-3
    two = _mat_file(tmp_path / "two.mat", True, a=np.ones((60, 3)), b=np.ones((60, 2)))
    with pytest.raises(HystdiscError) as exc:
        read_mat(two, columns={"t": 0, "theta": 1}, current=0.0)
    check_message(exc, "exactly one 2-D matrix", "found: a, b", "variable names")
    one = _mat_file(tmp_path / "one.mat", True, data=np.column_stack([t, np.sin(40 * t)]))
    with pytest.raises(HystdiscError) as exc:
        read_mat(one, columns={"t": 0, "theta": 99}, current=0.0)
    check_message(exc, "column index 99 is out of range for matrix 'data'", "from 0 to 59")
    ds = read_mat(one, columns={"t": 0, "theta": 1}, current=0.25)
    assert ds[0].current == 0.25 and np.array_equal(ds[0].t, t)
    first = _mat_file(tmp_path / "u.mat", True, theta=np.sin(40 * t), t=t)
    second = _mat_file(tmp_path / "y.mat", True, theta=np.cos(40 * t))
    with pytest.raises(HystdiscError) as exc:
        read_mat([first, second], current=0.0)
    check_message(exc, "variable 'theta' is in both", "u.mat and", "y.mat")


def test_mat_signal_of_another_experiment_is_ignored(tmp_path):
    t = np.arange(60) * 1e-3
    p = _mat_file(
        tmp_path / "r.mat", True, t=t, theta=np.sin(40 * t), torque=np.ones(7), current=0.5
    )
    ds = read_mat(p, experiment="release")  # the torque (of another length) is not read
    assert ds.experiment == "release" and ds[0].torque is None and ds[0].current == 0.5
    with pytest.raises(HystdiscError) as exc:
        read_mat(p)
    check_message(exc, "variable 'torque' has 7 samples but theta has 60")
