"""The fast training loop against a plain dense implementation of section III.

The dense reference below touches every weight at every step with the untruncated Gaussian envelope,
exactly as the paper writes the rules. The fast loop cuts the envelope at a square of half-width
h = ceil(cutoff * sigma) units, so every dropped envelope value is at most
e_cut = exp(-(h + 1)**2 / (2 sigma**2)). Per step a dropped unit's weight change is at most
rate * e_cut * |z - z~| (or epsilon * e_cut * |z^s - w|), with |.| <= 2 for codes and weights in
[0, 1]; after T steps with the same winners the weights differ by at most
T * max(eta * boost, epsilon) * 2 * e_cut, which is the tolerance used here (doubled for the
row normalisation, which can pass a change of one entry on to the others of its row).
"""

import numpy as np
import pytest

from associator import synthetic
from associator.network import Associator


def dense_reference(model_params: dict, vision, language, motor, changed, seed: int):
    """Returns (W_bu (768, 180), W_td (180, 768), winners) from the dense, float64 wake-sleep."""
    rows, cols = model_params["hidden_shape"]
    n_hidden = rows * cols
    sigma = model_params["envelope_sigma"]
    rng = np.random.default_rng(seed)
    w_bu = rng.random((rows, cols, 180))
    w_bu /= np.linalg.norm(w_bu, axis=2, keepdims=True)
    w_bu = w_bu.reshape(n_hidden, 180)
    w_td = (model_params["init_scale"] * rng.random((rows, cols, 180))).reshape(n_hidden, 180).T
    grid_r, grid_c = np.divmod(np.arange(n_hidden), cols)
    d2 = (grid_r[:, None] - grid_r[None]) ** 2 + (grid_c[:, None] - grid_c[None]) ** 2
    envelope = np.exp(-0.5 * d2 / sigma**2)  # row k: the code centred on unit k
    z_all = np.concatenate([vision, language, motor], axis=1)
    n = z_all.shape[0]
    dreams = np.minimum((rng.random((n, 1)) * n_hidden).astype(np.int64), n_hidden - 1)[:, 0]
    total, fraction = model_params["n_steps_total"], model_params["decay_fraction"]
    sign = 1.0 if model_params["sleep_sign"] == "self_organising" else -1.0
    winners = []
    for t in range(n):
        factor = min(1.0, max(0.0, (total - t) / (fraction * total)))
        z = z_all[t]
        k = int(np.argmax(w_bu @ z))
        winners.append(k)
        r_c = envelope[k]
        rate = (
            model_params["eta"] * factor * (model_params["motor_change_boost"] if changed[t] else 1)
        )
        w_td = np.maximum(w_td + rate * np.outer(z - w_td @ r_c, r_c), 0)
        z_sleep = w_td @ envelope[dreams[t]]
        r_c = envelope[int(np.argmax(w_bu @ z_sleep))]
        w_bu = w_bu + sign * model_params["epsilon"] * factor * r_c[:, None] * (z_sleep - w_bu)
        w_bu = np.maximum(w_bu, 0)
        w_bu /= np.linalg.norm(w_bu, axis=1, keepdims=True)
    return w_bu, w_td, np.array(winners)


@pytest.fixture(scope="module")
def stream():
    return synthetic.encode_stream(synthetic.teacher_stream(400, rng=3))


PARAMS = dict(eta=0.01, epsilon=0.05, n_steps_total=400, dtype="float64")


@pytest.mark.parametrize(
    "cutoff, sleep_sign",
    [(3.0, "self_organising"), (6.0, "self_organising"), (6.0, "printed")],
)
def test_fast_matches_dense_reference(stream, cutoff, sleep_sign):
    vision, language, motor, changed = stream
    model = Associator(envelope_cutoff=cutoff, sleep_sign=sleep_sign, rng=11, **PARAMS)
    model.fit(vision, language, motor, changed)
    params = model.get_params()
    w_bu, w_td, _ = dense_reference(params, vision, language, motor, changed, seed=11)
    half = np.ceil(cutoff * params["envelope_sigma"])
    e_cut = np.exp(-((half + 1) ** 2) / (2 * params["envelope_sigma"] ** 2))
    rate = max(params["eta"] * params["motor_change_boost"], params["epsilon"])
    tolerance = 2 * len(changed) * rate * 2 * e_cut + 1e-9
    assert np.abs(model.W_bu_ - w_bu).max() <= tolerance
    assert np.abs(model.W_td_ - w_td).max() <= tolerance
    # The weights moved far more than the tolerance: the comparison is not vacuous.
    assert np.abs(model.W_td_).max() > 10 * tolerance


def test_reference_detects_a_wrong_sign(stream):
    vision, language, motor, changed = stream
    model = Associator(sleep_sign="printed", rng=11, **PARAMS).fit(vision, language, motor, changed)
    params = dict(model.get_params(), sleep_sign="self_organising")
    w_bu, _, _ = dense_reference(params, vision, language, motor, changed, seed=11)
    assert np.abs(model.W_bu_ - w_bu).max() > 0.01


def test_float32_close_to_float64(stream):
    vision, language, motor, changed = stream
    fits = [
        Associator(rng=5, **dict(PARAMS, dtype=dtype)).fit(
            vision[:200], language[:200], motor[:200], changed[:200]
        )
        for dtype in ("float32", "float64")
    ]
    np.testing.assert_allclose(fits[0].W_bu_, fits[1].W_bu_, atol=1e-4)
    np.testing.assert_allclose(fits[0].W_td_, fits[1].W_td_, atol=1e-4)


@pytest.mark.parametrize("dtype, atol", [("float64", 1e-10), ("float32", 2e-5)])
def test_fast_loop_matches_general_loop(stream, monkeypatch, dtype, atol):
    """The fast loop (normalisation from the dense pass, no norms computed, window rows written
    through strided views) equals the plain per-phase loop up to rounding, through the decay."""
    vision, language, motor, changed = stream
    params = dict(PARAMS, dtype=dtype, n_steps_total=len(changed), decay_fraction=0.5)
    fast = Associator(rng=11, **params).fit(vision, language, motor, changed)
    monkeypatch.setattr(Associator, "_train_fast", Associator._train_general)
    general = Associator(rng=11, **params).fit(vision, language, motor, changed)
    np.testing.assert_allclose(fast.W_bu_, general.W_bu_, rtol=0, atol=atol)
    np.testing.assert_allclose(fast.W_td_, general.W_td_, rtol=0, atol=atol)
    assert np.abs(fast.W_td_).max() > 1000 * atol


@pytest.mark.parametrize("hidden_shape", [(16, 48), (48, 16), (5, 5), (3, 9)])
def test_storage_layout_holds_each_window_in_one_run(hidden_shape):
    """Each unit's run of storage rows holds its whole square window; the envelope on the run is
    the Gaussian inside the window and exactly 0 elsewhere; the order round-trips."""
    model = Associator(hidden_shape=hidden_shape, rng=0)
    model._initialise()
    layout = model._layout
    rows, cols = hidden_shape
    n = rows * cols
    assert sorted(layout.storage_of_grid) == list(range(n))
    np.testing.assert_array_equal(layout.storage_of_grid[layout.grid_of_storage], np.arange(n))
    grid_r, grid_c = np.divmod(np.arange(n), cols)
    half = int(np.ceil(model.envelope_cutoff * model.envelope_sigma))
    for i, k in enumerate(layout.grid_of_storage):
        dr, dc = grid_r - grid_r[k], grid_c - grid_c[k]
        inside = (np.abs(dr) <= half) & (np.abs(dc) <= half)
        expected = np.where(inside, np.exp(-0.5 * (dr**2 + dc**2)), 0.0)
        on_run = np.zeros(n)
        on_run[layout.grid_of_storage[layout.starts[i] : layout.stops[i]]] = layout.envelopes[i]
        np.testing.assert_allclose(on_run, expected, rtol=1e-12, atol=0)
    w_bu = np.random.default_rng(1).random((rows, cols, 180)).astype(np.float32)
    model._set_state(w_bu, w_bu, 0, None)
    np.testing.assert_array_equal(model.W_bu_, w_bu.reshape(n, 180))
    np.testing.assert_array_equal(model.W_td_, w_bu.reshape(n, 180).T)


def test_unit_rows_at_paper_size():
    """float32 at the paper's sizes and rates: rows stay unit length (the periodic renormalisation
    bounds the rounding of the per-step scale factors)."""
    data = synthetic.encode_stream(synthetic.teacher_stream(5000, rng=8))
    model = Associator(n_steps_total=10_000, rng=2).fit(*data)
    assert np.abs(np.linalg.norm(model.W_bu_, axis=1) - 1).max() < 1e-5
