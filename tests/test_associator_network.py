"""Tests of the associator network: training, read-outs, persistence, figures, bad input."""

import ast
import pathlib

import numpy as np
import pytest

from associator import encoding, figures, persistence, synthetic
from associator.encoding import DIRECTIVES, WORDS
from associator.network import Associator, ReadoutTables

N_LEARN = 30_000
LEARN_PARAMS = dict(hidden_shape=(8, 24), n_steps_total=N_LEARN, rng=0)


@pytest.fixture(scope="module")
def small_stream():
    return synthetic.encode_stream(synthetic.teacher_stream(600, rng=4))


@pytest.fixture(scope="module")
def learned():
    """A model trained on a synthetic teacher, and a held-out stream from another seed."""
    train = synthetic.encode_stream(synthetic.teacher_stream(N_LEARN, rng=1))
    model = Associator(**LEARN_PARAMS).fit(*train)
    test_stream = synthetic.teacher_stream(20_000, rng=2)
    return model, test_stream, synthetic.encode_stream(test_stream)


def balanced_accuracy(predicted: np.ndarray, truth: np.ndarray, n_classes: int) -> float:
    return float(np.mean([np.mean(predicted[truth == k] == k) for k in range(n_classes)]))


def test_learning_reaches_recognition_and_motor_recall_above_chance(learned):
    """Chance is 1/3 for recognition and 1/4 for motor recall (balanced over classes). With the
    printed sleep sign or no wake update this fails (recognition 0.33, motor recall <= 0.4)."""
    model, stream, (vision, _, motor, _) = learned
    recognised = model.recognise_batch(vision, motor)
    predicted = np.array([WORDS.index(w) for w in recognised.words])
    assert balanced_accuracy(predicted, stream.word, 3) > 0.5
    performed = model.perform_batch(vision, [WORDS[i] for i in stream.word])
    directives = np.array([DIRECTIVES.index(d) for d in performed.directives])
    assert balanced_accuracy(directives, stream.directive, 4) > 0.5
    # The words occupy separate regions: each word's most-used winner differs.
    peaks = {int(np.bincount(recognised.winners[predicted == k]).argmax()) for k in range(3)}
    assert len(peaks) == 3


def test_no_nan_and_constraints_hold(learned):
    model = learned[0]
    for weights in (model.W_bu_, model.W_td_):
        assert np.all(np.isfinite(weights)) and weights.min() >= 0
    np.testing.assert_allclose(np.linalg.norm(model.W_bu_, axis=1), 1, atol=1e-5)
    assert model.W_bu_.shape == (192, 180) and model.W_td_.shape == (180, 192)
    assert model.n_steps_ == N_LEARN


def test_paper_shapes(small_stream):
    model = Associator(rng=0).fit(*(a[:10] for a in small_stream))
    assert model.W_bu_.shape == (768, 180) and model.W_td_.shape == (180, 768)


def test_seeded_fits_are_identical(small_stream):
    a = Associator(rng=3).fit(*small_stream)
    b = Associator(rng=3).fit(*small_stream)
    c = Associator(rng=4).fit(*small_stream)
    np.testing.assert_array_equal(a.W_bu_, b.W_bu_)
    np.testing.assert_array_equal(a.W_td_, b.W_td_)
    assert not np.array_equal(a.W_td_, c.W_td_)


@pytest.mark.parametrize("sleep_sign", ["self_organising", "printed"])
def test_chunked_training_equals_one_call(small_stream, sleep_sign, tmp_path):
    params = dict(n_steps_total=600, decay_fraction=0.5, sleep_sign=sleep_sign, rng=7)
    whole = Associator(**params).fit(*small_stream)
    chunked = Associator(**params)
    pieces = [(0, 150), (150, 151), (151, 400), (400, 600)]
    for i, (start, stop) in enumerate(pieces):
        chunk = [a[start:stop] for a in small_stream]
        if i == 2:  # resume from a file in the middle
            path = persistence.save(chunked, tmp_path / "mid.npz")
            chunked = persistence.load(path)
        chunked.partial_fit(*chunk)
    np.testing.assert_array_equal(whole.W_bu_, chunked.W_bu_)
    np.testing.assert_array_equal(whole.W_td_, chunked.W_td_)
    assert chunked.n_steps_ == 600


def test_schedule():
    model = Associator(n_steps_total=1000, decay_fraction=0.25)
    assert model.learning_rate_factor(0) == 1.0
    assert model.learning_rate_factor(750) == 1.0
    assert model.learning_rate_factor(875) == pytest.approx(0.5)
    assert model.learning_rate_factor(1000) == 0.0


def test_inputs_not_modified(small_stream, learned):
    copies = [a.copy() for a in small_stream]
    Associator(rng=1).fit(*small_stream)
    for before, after in zip(copies, small_stream, strict=True):
        np.testing.assert_array_equal(before, after)
    model, _, (vision, _, motor, _) = learned
    v, m = vision[:50].copy(), motor[:50].copy()
    model.recognise_batch(v, m)
    model.perform_batch(v, "go")
    np.testing.assert_array_equal(v, vision[:50])
    np.testing.assert_array_equal(m, motor[:50])


def test_single_and_batch_read_outs_agree(learned):
    model, _, (vision, language, motor, _) = learned
    batch = model.recognise_batch(vision[:20], motor[:20])
    assert batch.scores.shape == (20, 3) and batch.words.shape == (20,)
    word, scores, hidden = model.recognise(vision[5], motor[5])
    assert word == batch.words[5] and word in WORDS
    np.testing.assert_allclose(scores, batch.scores[5])
    assert hidden.shape == (192,) and hidden.max() == 1.0
    directive, activations, hidden = model.perform(vision[5], "pick")
    assert directive in DIRECTIVES and activations.shape == (4,) and activations.min() >= 0
    assert directive == DIRECTIVES[int(np.argmax(activations))]
    batch = model.perform_batch(vision[:20], "pick")
    np.testing.assert_allclose(batch.motor[5], activations)
    by_code = model.perform_batch(vision[:20], np.tile(encoding.encode_word("pick"), (20, 1)))
    np.testing.assert_array_equal(by_code.winners, batch.winners)
    # An instruction is a word of the network's vocabulary, whichever (up to four phonemes).
    with pytest.raises(ValueError, match="unknown word 'stop'"):
        model.perform(vision[0], "stop")
    stop = Associator(vocabulary=WORDS + ("stop",), hidden_shape=(6, 12), rng=0)
    stop.fit(vision[:10], language[:10], motor[:10])
    assert stop.perform(vision[0], "stop").directive in DIRECTIVES


def test_save_load_round_trip(learned, tmp_path):
    model = learned[0]
    path = persistence.save(model, tmp_path / "model.npz", metadata={"arena_side_m": 4.0})
    loaded = persistence.load(path)
    np.testing.assert_array_equal(loaded.W_bu_, model.W_bu_)
    np.testing.assert_array_equal(loaded.W_td_, model.W_td_)
    assert loaded.get_params() == model.get_params()
    assert loaded.n_steps_ == model.n_steps_
    assert loaded.rng_.bit_generator.state == model.rng_.bit_generator.state
    assert persistence.load_metadata(path) == {"arena_side_m": 4.0}
    vision, motor = learned[2][0][:100], learned[2][2][:100]
    np.testing.assert_array_equal(
        loaded.recognise_batch(vision, motor).scores, model.recognise_batch(vision, motor).scores
    )


def test_corrupt_files_raise_value_error(learned, tmp_path):
    model = learned[0]
    good = pathlib.Path(persistence.save(model, tmp_path / "good.npz"))
    data = good.read_bytes()
    truncated = tmp_path / "truncated.npz"
    truncated.write_bytes(data[: len(data) // 2])
    garbage = tmp_path / "garbage.npz"
    garbage.write_bytes(b"not a zip file at all")
    with pytest.raises(ValueError, match="not a valid associator file"):
        persistence.load(truncated)
    with pytest.raises(ValueError, match="not a valid associator file"):
        persistence.load(garbage)
    with pytest.raises(ValueError, match="not a valid associator file"):
        persistence.load(tmp_path / "missing.npz")
    with np.load(good) as archive:
        entries = {key: archive[key] for key in archive.files}
    for change, match in [
        ({"format_version": np.array(99)}, "format_version 99"),
        ({"W_bu": entries["W_bu"][:10]}, "do not match hidden_shape"),
        ({"W_td": -entries["W_td"]}, "negative"),
        ({"params": np.array("{nonsense")}, "bad JSON"),
        ({"vocabulary_codes": entries["vocabulary_codes"] * 0}, "vocabulary"),
    ]:
        path = tmp_path / "changed.npz"
        np.savez(path, **dict(entries, **change))
        with pytest.raises(ValueError, match=match):
            persistence.load(path)
    path = tmp_path / "object.npz"
    np.savez(path, **dict(entries, metadata=np.array([{"a": 1}], dtype=object)))
    with pytest.raises(ValueError, match="not a valid associator file"):
        persistence.load(path)


@pytest.mark.parametrize(
    "params, match",
    [
        (dict(sleep_sign="minus"), "unknown sleep_sign 'minus'.*self_organising"),
        (dict(eta=-1.0), "eta must be a positive"),
        (dict(hidden_shape=(16,)), "hidden_shape"),
        (dict(dtype="float16"), "float32"),
        (dict(decay_fraction=2.0), r"decay_fraction must be in \[0, 1\]"),
        (dict(vocabulary=("go", "go")), "repeated"),
        (dict(vocabulary=("go", "xyzzyplugh")), "unknown word 'xyzzyplugh'"),
    ],
)
def test_bad_hyper_parameters(small_stream, params, match):
    with pytest.raises(ValueError, match=match):
        Associator(**params).fit(*(a[:5] for a in small_stream))


def test_bad_training_and_read_out_input(small_stream, learned):
    vision, language, motor, changed = (a[:5] for a in small_stream)
    model = learned[0]
    with pytest.raises(ValueError, match=r"vision codes must have shape \(n, 96\)"):
        Associator().fit(vision[:, :90], language, motor, changed)
    with pytest.raises(ValueError, match="finite"):
        Associator().fit(vision * np.nan, language, motor, changed)
    with pytest.raises(ValueError, match="motor code value -1.0 is out of range"):
        Associator().fit(vision, language, -motor, changed)
    with pytest.raises(ValueError, match="motor_changed must be a bool array of shape"):
        Associator().fit(vision, language, motor, changed[:3])
    with pytest.raises(ValueError, match="not fitted"):
        Associator().recognise(vision[0], motor[0])
    with pytest.raises(ValueError, match=r"vision code must have shape \(96,\)"):
        model.recognise(vision, motor[0])
    with pytest.raises(ValueError, match="unknown word 'xyzzyplugh'"):
        model.perform(vision[0], "xyzzyplugh")
    with pytest.raises(ValueError, match="same number of samples"):
        model.perform_batch(vision, ["go", "pick"])


def test_figures(learned, tmp_path):
    model, stream, (vision, _, motor, _) = learned
    paths = [
        figures.fig3_word_codes(tmp_path / "fig3.png"),
        figures.fig5_language_weights(model, tmp_path / "fig5.png"),
        figures.fig6_motor_weights(model, tmp_path / "fig6.png"),
        figures.fig7_hidden_activations(
            model,
            tmp_path / "fig7.png",
            recognition={
                w: (vision[stream.word == i], motor[stream.word == i]) for i, w in enumerate(WORDS)
            },
            performance={w: vision[stream.word == i] for i, w in enumerate(WORDS)},
        ),
    ]
    for path in paths:
        assert pathlib.Path(path).stat().st_size > 1000
    units = figures.select_language_units(model)
    codes = model.vocabulary_codes_
    assert len(units) == 4 and all(codes[:, units[3]] == 1)
    for i in range(3):
        assert codes[i, units[i]] == 1


def test_learn_inputs_is_partial_fit_on_the_assembled_input(small_stream):
    """``partial_fit`` is ``learn_inputs`` on ``encoding.assemble``'s input; once the schedule has
    reached zero the weights stay and its winners are the ones ``winners`` finds for them."""
    vision, language, motor, changed = small_stream
    params = dict(hidden_shape=(6, 12), n_steps_total=400, dtype="float64", rng=3)
    fitted = Associator(**params).partial_fit(vision, language, motor, changed)
    model = Associator(**params)
    z = encoding.assemble(vision, language, motor)
    winners = model.learn_inputs(z[:400], changed[:400])
    assert winners.shape == (400,) and winners.dtype == np.int64
    assert 0 <= winners.min() and winners.max() < model.n_hidden
    w_bu = model.W_bu_
    frozen = model.learn_inputs(z[400:], changed[400:])
    np.testing.assert_array_equal(model.W_bu_, w_bu)
    np.testing.assert_array_equal(model.W_bu_, fitted.W_bu_)
    np.testing.assert_array_equal(model.W_td_, fitted.W_td_)
    np.testing.assert_array_equal(frozen, model.winners(vision[400:], language[400:], motor[400:]))
    np.testing.assert_array_equal(frozen, np.argmax(z[400:] @ w_bu.T, axis=1))
    with pytest.raises(ValueError, match=r"input codes must have shape \(n, 180\)"):
        model.learn_inputs(z[:, :96])
    z[0, 0] = np.inf
    with pytest.raises(ValueError, match="finite"):
        model.learn_inputs(z)


def test_winners_and_readout_tables_are_the_read_outs(learned):
    """Recognition and performance are ``winners`` followed by a lookup in ``readout_tables``;
    ``winners`` takes any finite weighting of an area (a motor area times a gain)."""
    model, _, (vision, language, motor, _) = learned
    tables = model.readout_tables()
    assert isinstance(tables, ReadoutTables)
    assert tables.language.shape == (192, 80) and tables.motor.shape == (192, 4)
    assert tables.scores.shape == (192, 3) and not tables.motor.flags.writeable
    assert model.readout_tables() is tables  # cached
    recognised = model.recognise_batch(vision[:200], motor[:200], motor_weight=3.0)
    winners = model.winners(vision[:200], motor=3.0 * motor[:200])
    np.testing.assert_array_equal(recognised.winners, winners)
    np.testing.assert_array_equal(recognised.scores, tables.scores[winners])
    performed = model.perform_batch(vision[:200], "lift")
    winners = model.winners(vision[:200], language=np.tile(encoding.encode_word("lift"), (200, 1)))
    np.testing.assert_array_equal(performed.winners, winners)
    np.testing.assert_array_equal(performed.motor, tables.motor[winners])
    w_vision = np.ascontiguousarray(model.W_bu_[:, :96].T)  # float32, as the network computes
    np.testing.assert_array_equal(
        model.winners(vision[:200]), np.argmax(vision[:200].astype(np.float32) @ w_vision, axis=1)
    )
    with pytest.raises(ValueError, match="finite"):
        model.winners(vision[:2], motor=np.full((2, 4), np.nan))
    with pytest.raises(ValueError, match=r"motor codes must have shape \(n, 4\)"):
        model.winners(vision[:2], motor=motor[:2, :3])
    with pytest.raises(ValueError, match="samples"):
        model.winners(vision[:2], language=language[:3])
    with pytest.raises(ValueError, match="not fitted"):
        Associator().winners(vision[:2])


def test_the_read_out_weight_is_motor_weight(learned):
    model, _, (vision, _, motor, _) = learned
    weighted = model.recognise_batch(vision[:100], motor[:100], motor_weight=3.0)
    np.testing.assert_array_equal(
        weighted.winners, model.winners(vision[:100], motor=3.0 * motor[:100])
    )
    assert model.recognise(vision[0], motor[0], motor_weight=3.0).word == weighted.words[0]
    with pytest.raises(TypeError, match="motor_gain"):
        model.recognise_batch(vision[:2], motor[:2], motor_gain=3.0)
    with pytest.raises(TypeError, match="motor_gain"):
        model.recognise(vision[0], motor[0], motor_gain=3.0)
    with pytest.raises(ValueError, match="motor_weight must be a positive finite number"):
        model.recognise_batch(vision[:2], motor[:2], motor_weight=-1.0)


def test_unknown_words_are_refused(learned):
    """Performance takes the network's vocabulary only; the error names the word and it."""
    model, _, (vision, _, _, _) = learned
    vocabulary = r"the network's vocabulary: \('go', 'pick', 'lift'\)"
    with pytest.raises(ValueError, match=f"unknown word 'jump'; {vocabulary}"):
        model.perform(vision[0], "jump")
    with pytest.raises(ValueError, match=f"unknown word 'jump'; {vocabulary}"):
        model.perform_batch(vision[:3], "jump")
    with pytest.raises(ValueError, match="unknown words 'GO', 'jump'"):
        model.perform_batch(vision[:3], ["go", "jump", "GO"])


def test_from_state_rebuilds_the_network(learned):
    model, _, (vision, _, motor, _) = learned
    generator = np.random.default_rng(1)
    rebuilt = Associator.from_state(
        model.get_params(), model.W_bu_, model.W_td_, model.n_steps_, generator
    )
    assert rebuilt.rng_ is generator and rebuilt.n_steps_ == model.n_steps_
    np.testing.assert_array_equal(
        rebuilt.recognise_batch(vision[:100], motor[:100]).scores,
        model.recognise_batch(vision[:100], motor[:100]).scores,
    )
    for change, match in [
        (dict(params={**model.get_params(), "eta": -1.0}), "bad hyper-parameters.*eta"),
        (dict(params={**model.get_params(), "colour": 1}), "bad hyper-parameters"),
        (dict(W_bu=model.W_bu_[:5]), "do not match hidden_shape"),
        (dict(W_td=model.W_td_.astype(float)), "weights are float32/float64"),
        (dict(W_bu=-model.W_bu_), "W_bu has negative"),
        (dict(n_steps=-1), "n_steps must be an int >= 0"),
    ]:
        state = dict(
            params=model.get_params(),
            W_bu=model.W_bu_,
            W_td=model.W_td_,
            n_steps=model.n_steps_,
            generator=generator,
        )
        with pytest.raises(ValueError, match=match):
            Associator.from_state(**{**state, **change})


def test_saving_an_unfitted_model_raises(tmp_path):
    with pytest.raises(ValueError, match="not fitted"):
        persistence.save(Associator(), tmp_path / "a.npz")


def test_no_reach_into_other_classes_private_names():
    """Modules use other classes only through their public names: an attribute starting with one
    underscore is read only from ``self`` or ``cls`` (``network.Associator.from_state`` installs
    the state of the instance it creates)."""
    package = pathlib.Path(encoding.__file__).parent
    for source in package.glob("*.py"):
        tree = ast.parse(source.read_text())
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Attribute)
                and node.attr.startswith("_")
                and not node.attr.startswith("__")
            ):
                owner = node.value.id if isinstance(node.value, ast.Name) else None
                allowed = {"self", "cls"} | ({"model"} if source.name == "network.py" else set())
                assert owner in allowed, f"{source.name}:{node.lineno} .{node.attr}"


def test_no_simulator_imports():
    forbidden = {"mujoco", "dm_control", "cv2"}
    package = pathlib.Path(encoding.__file__).parent
    for source in package.glob("*.py"):
        tree = ast.parse(source.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            assert not {name.split(".")[0] for name in names} & forbidden, source
