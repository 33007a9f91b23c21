"""Camber network: numpy inference vs torch, range checks, storage round trip, training accuracy.

Training data come from a synthetic family of loaded camber profiles defined here (not a beam
model): a mm-deep pocket between two contact zones whose edges move with the load, plus a
cubic tip and tail rise. The gap meets the contact zones like distance², as a bent ski does.
"""

import itertools
import time

import h5py
import numpy as np
import pytest

torch = pytest.importorskip("torch", reason="torch is a test dependency (skisnow[test])")

from skisnow.app.training.check import beam_truth_profiles, contact_area_check  # noqa: E402
from skisnow.app.training.data import camber_training_arrays, split_load_cases  # noqa: E402
from skisnow.app.training.files import read_network_from_ski, write_network_to_ski  # noqa: E402
from skisnow.app.training.fit import train_camber_network  # noqa: E402
from skisnow.app.training.model import fold_members, smoothing_matrix, sum_networks, torch_predict  # noqa: E402
from skisnow.solvers import camber  # noqa: E402
from skisnow.solvers.errors import DataFileError, InputError, OutOfRangeError  # noqa: E402

LOADS_N = np.linspace(100.0, 700.0, 7)
POSITIONS_M = np.linspace(-0.25, 0.05, 5)
GRID_M = np.linspace(-1.0, 1.0, 2001)  # 1 mm spacing over a 2 m ski


def synthetic_profiles(loads_n, load_positions_m, positions_m):
    """Loaded gap H*(X) [m] of a synthetic ski for loads (F [N], x_F [m]); shape (K, M)."""
    x = np.asarray(positions_m)[None, :]
    f = np.asarray(loads_n, dtype=float)[:, None] / 700.0
    xf = np.asarray(load_positions_m, dtype=float)[:, None] + 0.1
    centre = 0.3 * xf + 0.02 * f
    half_width = 0.62 - 0.14 * f + 0.1 * xf
    depth = 1.4e-3 * (1 - 0.55 * f) * (1 - 0.8 * xf)
    u = (x - centre) / half_width
    pocket = depth * np.clip(1 - u**2, 0, None) ** 2 * (1 + 0.4 * u * xf / 0.15)
    tip = 0.02 * np.clip((x - 0.8) / 0.2, 0, None) ** 3 * (1 + 0.1 * f)
    tail = 0.01 * np.clip((-0.85 - x) / 0.15, 0, None) ** 3
    return pocket + tip + tail


def _cases():
    f, xf = np.meshgrid(LOADS_N, POSITIONS_M, indexing="ij")
    return f.ravel(), xf.ravel()


@pytest.fixture(scope="module")
def trained():
    f, xf = _cases()
    h = synthetic_profiles(f, xf, GRID_M)
    result = train_camber_network_short(f, xf, h, seed=0)
    return result, (f, xf, h)


def train_camber_network_short(f, xf, h, seed, epochs=300, lbfgs_epochs=150, **kwargs):
    # tanh suits this smooth family (the demo skis' beam data, with kinks where contacts appear,
    # default to relu); smoothing and the other settings are the defaults
    kwargs.setdefault("activation", "tanh")
    return train_camber_network(
        GRID_M,
        f,
        xf,
        h,
        epochs=epochs,
        lbfgs_epochs=lbfgs_epochs,
        seed=seed,
        ski_id="synthetic",
        **kwargs,
    )


def test_synthetic_family_is_a_loaded_camber():
    f, xf = _cases()
    h = synthetic_profiles(f, xf, GRID_M)
    assert (h >= 0).all()
    contact = (h == 0).mean(axis=1)
    assert ((contact > 0.1) & (contact < 0.5)).all()  # two contact zones on every profile
    pocket = h[:, np.abs(GRID_M) < 0.4].max(axis=1)
    assert ((pocket > 0.3e-3) & (pocket < 2e-3)).all()  # a few 0.1 mm to mm under the pocket


def test_held_out_accuracy(trained):
    """Held-out load cases: RMSE of H* where H* < 0.2 mm within the 5 µm target.

    Measured 2.7 µm with this short training (300 Adam + 150 L-BFGS epochs, tanh, 10 mm output
    smoothing); without smoothing 1.6 µm, and a long training ~0.6 µm. The length where
    H* ≤ 5 µm must match to 1 % of the ski (measured ≤ 0.5 % on average).
    """
    result, _ = trained
    m = result.metrics
    assert m["test_n_cases"] >= 4 and m["validation_n_cases"] >= 4
    assert m["test_rmse_band_m"] < 5e-6
    assert m["validation_rmse_band_m"] < 5e-6
    assert m["test_contact_fraction_error"] < 0.01
    # the metrics are stored with the network
    assert result.network["attrs"]["metric_test_rmse_band_m"] == m["test_rmse_band_m"]


def test_numpy_inference_matches_torch(trained):
    result, _ = trained
    net = result.network
    rng = np.random.default_rng(1)
    f = rng.uniform(net["attrs"]["load_min_n"], net["attrs"]["load_max_n"], 50)
    xf = rng.uniform(net["attrs"]["load_position_min_m"], net["attrs"]["load_position_max_m"], 50)
    ours = camber.predict_profiles(net, f, xf).gaps_m
    ref = torch_predict(net, f, xf)
    assert ours.shape == (50, GRID_M.size)
    np.testing.assert_allclose(ours, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())
    # and not trivially: the gaps vary with the load
    assert np.ptp(ours[:, GRID_M.size // 2]) > 1e-4


def test_prediction_nonnegative_with_exact_contact(trained):
    result, _ = trained
    x, gap = camber.predict_profile(result.network, 392.8, -0.16)
    np.testing.assert_array_equal(x, GRID_M)
    assert (gap >= 0).all()
    assert 0.1 < (gap == 0).mean() < 0.5  # exact zeros in the contact zones
    dense = camber.predict_profiles(
        result.network, np.linspace(100, 700, 31), np.linspace(-0.25, 0.05, 31)
    ).gaps_m
    assert (dense >= 0).all()


def test_single_and_vectorised_agree(trained):
    net = trained[0].network
    _, one = camber.predict_profile(net, 300.0, -0.1)
    many = camber.predict_profiles(net, [100.0, 300.0], [0.0, -0.1]).gaps_m
    np.testing.assert_allclose(one, many[1], rtol=1e-12, atol=1e-18)


@pytest.mark.parametrize(
    ("load", "pos", "name"),
    [
        (99.0, -0.1, "loads_n"),
        (700.5, -0.1, "loads_n"),
        (300.0, -0.26, "load_positions_m"),
        (300.0, 0.06, "load_positions_m"),
    ],
)
def test_out_of_range_raises(trained, load, pos, name):
    net = trained[0].network
    with pytest.raises(OutOfRangeError, match=name) as info:
        camber.predict_profile(net, load, pos)
    assert "trained range" in str(info.value)


def test_range_edges_and_bad_inputs(trained):
    net = trained[0].network
    camber.predict_profile(
        net, net["attrs"]["load_min_n"], net["attrs"]["load_position_max_m"]
    )  # edges are in
    with pytest.raises(InputError, match="finite"):
        camber.predict_profile(net, float("nan"), -0.1)
    with pytest.raises(InputError, match="finite"):
        camber.predict_profiles(net, [300.0, 300.0], [-0.1, np.inf])
    with pytest.raises(InputError, match="equal length"):
        camber.predict_profiles(net, [300.0, 300.0], [-0.1])


def test_inference_time_below_one_ms(trained):
    net = trained[0].network
    times = []
    for _ in range(300):
        t0 = time.perf_counter()
        camber.predict_profile(net, 392.8, -0.16)
        times.append(time.perf_counter() - t0)
    assert np.median(times) < 1e-3


def _assert_same_network(back, net):
    assert set(back) == set(net)
    assert back["attrs"] == net["attrs"]
    for key, value in back["attrs"].items():
        assert type(value) is type(net["attrs"][key]), key
    for key, value in net.items():
        if key != "attrs":
            np.testing.assert_array_equal(back[key], value)
            assert back[key].dtype == value.dtype, key


def test_hdf5_round_trip(trained, tmp_path):
    net = trained[0].network
    path = tmp_path / "ski.h5"
    with h5py.File(path, "w") as fh:
        fh.attrs["ski_id"] = "synthetic"
        fh.create_dataset("other", data=np.arange(3))
    write_network_to_ski(path, net)
    write_network_to_ski(path, net)  # replacing an existing group works too
    back = read_network_from_ski(path)
    _assert_same_network(back, net)
    f, xf = [150.0, 650.0], [-0.2, 0.0]
    np.testing.assert_array_equal(
        camber.predict_profiles(back, f, xf).gaps_m, camber.predict_profiles(net, f, xf).gaps_m
    )
    with h5py.File(path, "r") as fh:  # the rest of the file is untouched; no pickles
        np.testing.assert_array_equal(fh["other"][()], np.arange(3))
        assert fh.attrs["ski_id"] == "synthetic"
        assert fh["network"].attrs["schema"] == camber.SCHEMA
        assert all(d.dtype.kind in "fiu" for d in fh["network"].values())


def test_round_trip_through_ski_storage(trained, tmp_path):
    """The network survives write_ski/read_ski of app.storage.skis unchanged."""
    skis = pytest.importorskip("skisnow.app.storage.skis")
    net = trained[0].network
    f, xf = _cases()
    data = skis.CamberData(
        ski_id="synthetic",
        positions_m=GRID_M,
        loads_n=f,
        load_positions_m=xf,
        sides=["mean"] * f.size,
        profiles_m=synthetic_profiles(f, xf, GRID_M),
    )
    outline = skis.SkiOutline(2.0, 1.0, np.array([-1.0, 1.0]), np.array([0.044, 0.044]))
    path = tmp_path / "ski.h5"
    skis.write_ski(path, skis.SkiRecord(data, outline), network=net)
    _assert_same_network(camber.network_to_dict(skis.read_ski(path).network), net)
    # and the in-place update keeps the measurements readable by the storage module
    write_network_to_ski(path, net)
    record = skis.read_ski(path)
    np.testing.assert_array_equal(record.measurements.profiles_m, data.profiles_m)
    _assert_same_network(camber.network_to_dict(record.network), net)


def test_schema_is_checked(trained):
    net = dict(trained[0].network)
    net["attrs"] = {**net["attrs"], "schema": "skisnow.camber-mlp/0"}
    with pytest.raises(DataFileError, match="schema"):
        camber.network_to_dict(net)
    net = dict(trained[0].network)
    net["layer1_weight"] = net["layer1_weight"][:, :3]
    with pytest.raises(DataFileError, match="layer 1"):
        camber.check_network(net)
    net = dict(trained[0].network)
    del net["output_scale"]
    with pytest.raises(DataFileError, match="output_scale"):
        camber.network_to_dict(net)


def test_split_holds_out_interior_cases_only():
    f, xf = _cases()
    split = split_load_cases(f, xf, validation_fraction=0.15, test_fraction=0.15)
    held = np.concatenate([split["validation"], split["test"]])
    assert np.intersect1d(held, split["train"]).size == 0
    assert np.union1d(held, split["train"]).size == f.size
    assert (f[held] > f.min()).all() and (f[held] < f.max()).all()
    assert (xf[held] > xf.min()).all() and (xf[held] < xf.max()).all()
    with pytest.raises(InputError, match="interior"):
        split_load_cases(f[:5], xf[:5])


def test_training_is_deterministic():
    f, xf = _cases()
    h = synthetic_profiles(f, xf, GRID_M)
    a = train_camber_network_short(f, xf, h, seed=3, epochs=40, lbfgs_epochs=10).network
    b = train_camber_network_short(f, xf, h, seed=3, epochs=40, lbfgs_epochs=10).network
    c = train_camber_network_short(f, xf, h, seed=4, epochs=40, lbfgs_epochs=10).network
    for i in range(int(a["attrs"]["n_layers"])):
        np.testing.assert_array_equal(a[f"layer{i}_weight"], b[f"layer{i}_weight"])
        np.testing.assert_array_equal(a[f"layer{i}_bias"], b[f"layer{i}_bias"])
    assert not np.array_equal(a["layer0_weight"], c["layer0_weight"])


def test_training_rejects_bad_data():
    f, xf = _cases()
    h = synthetic_profiles(f, xf, GRID_M)
    bad = h.copy()
    bad[0, 5] = -60e-6  # below the device-noise allowance of -50 µm
    with pytest.raises(InputError, match="profiles_m must be >="):
        train_camber_network(GRID_M, f, xf, bad, epochs=1)
    bad[0, 5] = np.nan
    with pytest.raises(InputError, match="NaN"):
        train_camber_network(GRID_M, f, xf, bad, epochs=1)
    with pytest.raises(InputError, match="shape"):
        train_camber_network(GRID_M, f, xf, h[:, :-1], epochs=1)


def _relu(a):
    return np.maximum(a, 0.0)


def _mlp(z, weights, biases, sigma):
    """Plain numpy MLP: hidden layers with ``sigma``, linear last layer."""
    a = z
    for i, (w, b) in enumerate(zip(weights, biases, strict=True)):
        a = a @ w.T + b
        if i < len(weights) - 1:
            a = sigma(a)
    return a


def test_ensemble_fold_equals_mean_of_members():
    """Folding members into one MLP (stacked, block-diagonal) gives the mean of their outputs."""
    rng = np.random.default_rng(5)
    sizes = [2, 8, 6, 5]
    members = [
        {
            "weights": [rng.normal(size=(o, i)) for i, o in itertools.pairwise(sizes)],
            "biases": [rng.normal(size=o) for o in sizes[1:]],
        }
        for _ in range(3)
    ]
    nodes = np.linspace(0.0, 0.04, 5)
    off, scale = rng.normal(size=5), rng.uniform(0.5, 2.0, size=5)
    g = smoothing_matrix(nodes, 0.01)
    np.testing.assert_allclose(g.sum(axis=1), 1.0)
    weights, biases = fold_members(members, off, scale, g)
    z = rng.normal(size=(4, 2))
    mean = np.mean(
        [(off + scale * _mlp(z, m["weights"], m["biases"], _relu)) @ g.T for m in members], 0
    )
    np.testing.assert_allclose(
        g @ off + _mlp(z, weights, biases, _relu), mean, rtol=1e-12, atol=1e-12
    )


@pytest.mark.parametrize("sizes", [[2, 7, 5, 4], [2, 4]])
def test_sum_networks_output_is_the_sum(sizes):
    """sum_networks (used by the ensemble fold and the residual stage) adds member outputs."""
    rng = np.random.default_rng(9)
    members = [
        (
            [rng.normal(size=(o, i)) for i, o in itertools.pairwise(sizes)],
            [rng.normal(size=o) for o in sizes[1:]],
        )
        for _ in range(2)
    ]
    weights, biases = sum_networks(members)
    z = rng.normal(size=(6, 2))
    expected = sum(_mlp(z, w, b, np.tanh) for w, b in members)
    np.testing.assert_allclose(_mlp(z, weights, biases, np.tanh), expected, rtol=1e-12, atol=1e-12)
    with pytest.raises(InputError):
        extra = (members[1][0] + members[1][0][-1:], members[1][1] + members[1][1][-1:])
        sum_networks([members[0], extra])


def test_signed_node_gaps_interpolate_to_the_prediction(trained):
    """predict_profiles is the ReLU of the node signed gaps interpolated onto the grid."""
    net = trained[0].network
    f, xf = np.array([250.0, 520.0]), np.array([-0.2, 0.0])
    s = camber.signed_node_gaps(net, np.stack([f, xf], axis=1))
    assert s.shape == (2, np.asarray(net["node_positions_m"]).size)
    expected = np.maximum(
        [np.interp(net["positions_m"], net["node_positions_m"], row) for row in s], 0.0
    )
    got = camber.predict_profiles(net, f, xf).gaps_m
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-15)


def test_relu_ensemble_numpy_matches_torch():
    f, xf = _cases()
    h = synthetic_profiles(f, xf, GRID_M)
    net = train_camber_network_short(
        f, xf, h, seed=1, epochs=20, lbfgs_epochs=5, activation="relu", ensemble=2
    ).network
    assert net["layer1_weight"].shape == (128, 128)  # two members folded
    assert (net["layer1_weight"][:64, 64:] == 0).all()
    loads = np.linspace(150.0, 650.0, 7)
    pos = np.linspace(-0.2, 0.0, 7)
    ours = camber.predict_profiles(net, loads, pos).gaps_m
    ref = torch_predict(net, loads, pos)
    np.testing.assert_allclose(ours, ref, rtol=1e-6, atol=1e-6 * np.abs(ref).max())


def test_contact_area_check_reports_errors(trained):
    """Macro-BEM check: zero error against the network's own profiles, large against a shift."""
    pytest.importorskip("skisnow.solvers.macro")
    net = trained[0].network
    loads, pos = np.array([392.8]), np.array([-0.16])
    own = camber.predict_profiles(net, loads, pos).gaps_m
    kwargs = {"width_m": 0.044, "effective_modulus_pa": 3.4e8}
    same = contact_area_check(net, loads, pos, own, **kwargs)
    assert same["converged"]
    assert same["max_abs_relative_error"] == 0.0
    assert same["area_true_m2"][0] > 0
    rough = own + 2e-6 * np.random.default_rng(0).standard_normal(own.shape)
    worse = contact_area_check(net, loads, pos, np.maximum(rough, 0), **kwargs)
    assert worse["max_abs_relative_error"] > 0.03


def test_cli_trains_and_writes_network(tmp_path, capsys):
    """skisnow train-camber on a small ski file: network group written, metrics printed."""
    skis = pytest.importorskip("skisnow.app.storage.skis")
    from skisnow.app import cli

    f, xf = _cases()
    data = skis.CamberData(
        ski_id="cli-ski",
        positions_m=GRID_M,
        loads_n=f,
        load_positions_m=xf,
        sides=["mean"] * f.size,
        profiles_m=synthetic_profiles(f, xf, GRID_M),
    )
    outline = skis.SkiOutline(2.0, 1.0, np.array([-1.0, 1.0]), np.array([0.044, 0.044]))
    path = tmp_path / "cli-ski.h5"
    skis.write_ski(path, skis.SkiRecord(data, outline))
    argv = ["train-camber", "--ski", str(path), "--epochs", "5", "--lbfgs-epochs", "0"]
    assert cli.main([*argv, "--ensemble", "1"]) == 0
    out = capsys.readouterr().out
    assert "cli-ski" in out and "RMSE(H*<0.2 mm)" in out
    record = skis.read_ski(path)
    net = camber.network_to_dict(record.network)
    assert net["attrs"]["ski_id"] == "cli-ski" and net["attrs"]["measured_side"] == "mean"
    np.testing.assert_array_equal(record.measurements.profiles_m, data.profiles_m)
    # a missing ski file is a one-line error with exit status 2
    assert cli.main(["train-camber", "--ski", str(tmp_path / "nope.h5")]) == 2
    assert "not found" in capsys.readouterr().err


def test_sides_left_right_are_averaged():
    from types import SimpleNamespace

    x = np.linspace(0.0, 1.0, 5)
    h = np.arange(20.0).reshape(4, 5) * 1e-6
    data = SimpleNamespace(
        ski_id="s",
        positions_m=x,
        loads_n=np.array([100.0, 100.0, 200.0, 200.0]),
        load_positions_m=np.array([0.0, 0.0, 0.1, 0.1]),
        sides=["left", "right", "right", "left"],
        profiles_m=h,
    )
    _, _, f, xf, prof, side = camber_training_arrays(data)
    assert side == "left+right"
    np.testing.assert_array_equal(f, [100.0, 200.0])
    np.testing.assert_array_equal(xf, [0.0, 0.1])
    np.testing.assert_allclose(prof, [(h[0] + h[1]) / 2, (h[2] + h[3]) / 2])
    data.sides = ["left", "right", "right", "right"]
    data.load_positions_m = np.array([0.0, 0.0, 0.1, 0.2])
    with pytest.raises(InputError, match="one side only"):
        camber_training_arrays(data)
    data.sides = ["mean", "left", "right", "mean"]
    _, _, f, _, prof, side = camber_training_arrays(data)
    assert side == "mean" and f.size == 2


DEMO_SKIS = ("ski-a", "ski-b")


def _demo_ski(name: str):
    """The shipped demo ski record and its network dict."""
    from skisnow.app.storage.common import REPO_ROOT
    from skisnow.app.storage.skis import read_ski

    record = read_ski(REPO_ROOT / "tables" / "skis" / f"{name}.h5")
    return record, camber.network_to_dict(record.network)


@pytest.mark.parametrize("name", DEMO_SKIS)
def test_demo_ski_network_against_beam_truth(name):
    """The shipped demo networks against their noise-free beam model (held-out loads).

    Full check with the macro BEM: ``skisnow train-camber --ski NAME`` (stored as
    ``metric_truth_*``, docs/camber-network.md). Here: RMSE of H* where H* < 0.2 mm on 8 loads
    drawn in the trained range (measured ≈1 µm, target 5 µm).
    """
    record, net = _demo_ski(name)
    a = net["attrs"]
    rng = np.random.default_rng(7)
    f = rng.uniform(a["load_min_n"], a["load_max_n"], 8)
    xf = rng.uniform(a["load_position_min_m"], a["load_position_max_m"], 8)
    truth = beam_truth_profiles(record.beam, net["positions_m"], f, xf)
    pred = camber.predict_profiles(net, f, xf).gaps_m
    band = truth < camber.CONTACT_BAND_M
    assert np.sqrt(np.mean((pred - truth)[band] ** 2)) < 2.5e-6
    # the stored metrics of the full check are there and meet the RMSE target
    assert a["metric_truth_rmse_band_random_m"] < 5e-6
    assert a["metric_truth_rmse_band_test_m"] < 5e-6


def _demo_area_errors(name: str, n_random: int = 12) -> tuple[np.ndarray, np.ndarray]:
    """Loads and relative apparent-area errors (network vs beam truth, macro BEM) of a demo ski.

    Cases: the papers' 40 kg at −160 mm first, then ``n_random`` loads drawn uniformly (seed 11)
    from the trained range; E_snow = 200 MPa, default macro grid, tilt on.
    """
    from skisnow.solvers.beam import G_STANDARD
    from skisnow.solvers.elastic import effective_modulus

    record, net = _demo_ski(name)
    a = net["attrs"]
    rng = np.random.default_rng(11)
    f = np.concatenate(
        [[40.0 * G_STANDARD], rng.uniform(a["load_min_n"], a["load_max_n"], n_random)]
    )
    xf = np.concatenate(
        [[-0.160], rng.uniform(a["load_position_min_m"], a["load_position_max_m"], n_random)]
    )
    truth = beam_truth_profiles(record.beam, net["positions_m"], f, xf)
    check = contact_area_check(
        net,
        f,
        xf,
        truth,
        width_m=record.outline.width_m,
        width_positions_m=record.outline.positions_m,
        effective_modulus_pa=effective_modulus(200e6),
    )
    assert check["converged"]
    return f, check["relative_error"]


@pytest.mark.parametrize("name", DEMO_SKIS)
def test_demo_ski_network_apparent_area_papers_case_and_median(name):
    """Apparent area from the network vs from the true profile (issue #3 target: 3 %).

    Met for the papers' case and in the median over random loads in range (stored full check:
    median 1.1 % / 0.9 %); the light-load misses are the strict xfail below.
    """
    _, err = _demo_area_errors(name)
    assert abs(err[0]) <= 0.03, f"papers' case: {err[0]:+.1%}"
    assert np.median(np.abs(err)) <= 0.03, f"median |error| {np.median(np.abs(err)):.1%}"


@pytest.mark.xfail(
    strict=True,
    reason="known gap (issue #3; docs/camber-network.md, 'What limits the area accuracy'): at "
    "light loads (~100-400 N) the apparent area reacts to sub-µm profile errors, and the "
    "network trained on 3 µm-noise measurements is 0.5-1 µm off",
)
@pytest.mark.parametrize("name", DEMO_SKIS)
def test_demo_ski_network_apparent_area_within_3_percent_everywhere(name):
    f, err = _demo_area_errors(name)
    worst = int(np.argmax(np.abs(err)))
    assert np.all(np.abs(err) <= 0.03), f"{err[worst]:+.1%} at {f[worst]:.0f} N"


def test_remeasure_keeps_the_calibrated_beam(tmp_path, monkeypatch):
    """make_demo_skis --remeasure changes only the measurements, never the ski's beam model."""
    import importlib.util

    from skisnow.app.storage.common import REPO_ROOT
    from skisnow.app.storage.skis import read_ski

    spec = importlib.util.spec_from_file_location(
        "make_demo_skis", REPO_ROOT / "scripts" / "make_demo_skis.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    monkeypatch.setattr(script, "MEASURE_LOADS_KG", np.array([20.0, 60.0]))
    monkeypatch.setattr(script, "MEASURE_POSITIONS_M", np.array([-0.2, 0.0, 0.1]))
    src = REPO_ROOT / "tables" / "skis" / "ski-b.h5"
    (tmp_path / "ski-b.h5").write_bytes(src.read_bytes())
    script.remeasure("ski-b", tmp_path)
    old, new = read_ski(src), read_ski(tmp_path / "ski-b.h5")
    for key in ("positions_m", "bending_stiffness_nm2", "unloaded_gap_m"):
        np.testing.assert_array_equal(getattr(new.beam, key), getattr(old.beam, key))
    assert new.beam_design == old.beam_design
    assert new.measurements.profiles_m.shape == (6, old.beam.positions_m.size)
    np.testing.assert_array_equal(new.measurements.loads_n, np.repeat([20.0, 60.0], 3) * 9.82)
    assert new.network is None
    with h5py.File(src) as a, h5py.File(tmp_path / "ski-b.h5") as b:
        assert a.attrs["parameters_json"] == b.attrs["parameters_json"]


def test_add_unloaded_keeps_the_loaded_cases_and_appends_the_camber(tmp_path):
    """make_demo_skis --add-unloaded (#26): the loaded cases and the network stay bit for bit, one
    case of load 0 is appended whose profile is the true camber plus 3 µm noise of its own seed."""
    import importlib.util

    from skisnow.app.storage.common import REPO_ROOT
    from skisnow.app.storage.skis import read_ski

    spec = importlib.util.spec_from_file_location(
        "make_demo_skis", REPO_ROOT / "scripts" / "make_demo_skis.py"
    )
    script = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(script)
    src = REPO_ROOT / "tables" / "skis" / "ski-a.h5"
    old = read_ski(src)
    loaded = old.measurements.loads_n > 0
    (tmp_path / "ski-a.h5").write_bytes(src.read_bytes())
    script.add_unloaded("ski-a", tmp_path)
    new = read_ski(tmp_path / "ski-a.h5")
    m = new.measurements
    assert m.loads_n.size == int(loaded.sum()) + 1 and m.loads_n[-1] == 0.0
    np.testing.assert_array_equal(m.profiles_m[:-1], old.measurements.profiles_m[loaded])
    np.testing.assert_array_equal(m.loads_n[:-1], old.measurements.loads_n[loaded])
    residual = m.profiles_m[-1] - new.beam.unloaded_gap_m
    assert 2.7e-6 < residual.std() < 3.3e-6 and abs(residual.mean()) < 0.3e-6
    for key in ("positions_m", "bending_stiffness_nm2", "unloaded_gap_m"):
        np.testing.assert_array_equal(getattr(new.beam, key), getattr(old.beam, key))
    assert new.network is not None and old.network is not None
    np.testing.assert_array_equal(new.network["attrs"]["schema"], old.network["attrs"]["schema"])
    assert script.add_unloaded("ski-a", tmp_path)["unloaded"] == "already measured"
