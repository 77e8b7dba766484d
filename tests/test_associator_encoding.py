"""Tests of the associator's input codes: vision, language and motor."""

import numpy as np
import pytest

from associator import encoding
from associator.encoding import DIRECTIVES, N_INPUT, WORDS, VisionEncoder


def test_layout_constants():
    assert WORDS == ("go", "pick", "lift")
    assert DIRECTIVES == ("forward", "backward", "turn_right", "turn_left")
    assert (encoding.N_VISION, encoding.N_LANGUAGE, encoding.N_MOTOR, N_INPUT) == (96, 80, 4, 180)
    assert encoding.MOTOR_SLICE.stop == N_INPUT


def test_vision_units_at_the_documented_places():
    enc = VisionEncoder(half_side_m=2.0)
    at_wall = enc.encode(0.0, 0.0, 0.0)
    assert np.argmax(at_wall[encoding.X_SLICE]) == 0
    assert np.argmax(enc.encode(2.0, 0.0, 0.0)[encoding.X_SLICE]) == 35
    y_code = at_wall[encoding.Y_SLICE]
    assert y_code[17] == pytest.approx(y_code[18])  # y = 0 lies between the two middle units
    assert np.argmax(at_wall[encoding.PHI_SLICE]) == 12
    assert at_wall.min() >= 0 and at_wall.max() <= 1
    # Truncated at 3 units: at most 7 active units per coordinate.
    assert np.count_nonzero(enc.encode(1.0, 0.3, 40.0)) <= 21


def test_vision_round_trip():
    enc = VisionEncoder(half_side_m=2.0)
    rng = np.random.default_rng(0)
    x = rng.uniform(0, 2, 500)
    y = rng.uniform(-2, 2, 500)
    phi = rng.uniform(-180, 180, 500)
    decoded = enc.decode_batch(enc.encode_batch(x, y, phi))
    np.testing.assert_allclose(decoded[:, 0], x, atol=1e-6)
    np.testing.assert_allclose(decoded[:, 1], y, atol=1e-6)
    dphi = (decoded[:, 2] - phi + 180) % 360 - 180
    np.testing.assert_allclose(dphi, 0, atol=1e-6)


def test_vision_code_centres_are_in_units_of_the_code_whatever_the_arena():
    """The bump centres are the poses in units of each population's spacing: x over [0, 35], y
    over [0, 35], phi over [0, 24) with 0 deg at unit 12; the same for a 4 m and a 6 m arena."""
    rng = np.random.default_rng(1)
    for half in (2.0, 3.0):
        enc = VisionEncoder(half_side_m=half)
        x, y, phi = (
            rng.uniform(0, half, 200),
            rng.uniform(-half, half, 200),
            rng.uniform(-180, 180, 200),
        )
        centres = encoding.vision_code_centres(enc.encode_batch(x, y, phi))
        np.testing.assert_allclose(centres[:, 0], x / half * 35, atol=1e-6)
        np.testing.assert_allclose(centres[:, 1], (y + half) / (2 * half) * 35, atol=1e-6)
        expected = ((phi + 180) / 15) % 24
        np.testing.assert_allclose((centres[:, 2] - expected + 12) % 24 - 12, 0, atol=1e-6)
        assert np.all((centres[:, 2] >= 0) & (centres[:, 2] < 24))


def test_phi_is_circular():
    enc = VisionEncoder(half_side_m=2.0)
    np.testing.assert_allclose(enc.encode(1, 0, 180.0), enc.encode(1, 0, -180.0), atol=1e-12)
    near_plus, near_minus = enc.encode(1, 0, 179.0), enc.encode(1, 0, -179.0)
    phi = encoding.PHI_SLICE
    assert np.dot(near_plus[phi], near_minus[phi]) > 0.8 * np.dot(near_plus[phi], near_plus[phi])
    assert enc.decode(enc.encode(1, 0, 179.0))[2] == pytest.approx(179.0, abs=1e-6)


def test_arena_sets_the_ranges():
    enc = VisionEncoder.from_arena_side(6.0)
    assert enc.half_side_m == 3.0
    assert np.argmax(enc.encode(3.0, 0, 0)[encoding.X_SLICE]) == 35
    with pytest.raises(ValueError, match=r"x = 2.5 .*allowed: \[0.0, 2.0\]"):
        VisionEncoder(half_side_m=2.0).encode(2.5, 0, 0)


@pytest.mark.parametrize(
    "args, match",
    [
        ((-0.1, 0, 0), "x = -0.1"),
        ((1, 2.1, 0), "y = 2.1"),
        ((1, 0, 181), "phi = 181"),
        ((np.nan, 0, 0), "finite"),
        ((1, 0, np.inf), "finite"),
    ],
)
def test_vision_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        VisionEncoder(half_side_m=2.0).encode(*args)


def test_vision_clip_and_shapes():
    enc = VisionEncoder(half_side_m=2.0)
    np.testing.assert_array_equal(enc.encode(-0.1, 3, 0, clip=True), enc.encode(0, 2, 0))
    with pytest.raises(ValueError, match="one shape"):
        enc.encode_batch([1, 1], [0], [0])
    with pytest.raises(ValueError, match="positive"):
        VisionEncoder(half_side_m=0)


def test_the_arena_size_is_required_and_checked():
    """The encoder has no arena of its own: ``half_side_m`` is a required keyword, a positive
    finite number of metres."""
    with pytest.raises(TypeError, match="half_side_m"):
        VisionEncoder()
    with pytest.raises(TypeError):
        VisionEncoder(2.0)  # keyword only
    for bad in (-1.0, np.inf, np.nan, "2"):
        with pytest.raises(ValueError, match="half_side_m must be a positive finite number"):
            VisionEncoder(half_side_m=bad)


def test_phoneme_table():
    table = encoding.phoneme_table()
    assert len(table.phonemes) == 46 and table.codes.shape == (46, 20)
    assert len(table.features) == 20
    assert len({tuple(row) for row in table.codes}) == 46  # all distinct
    assert set(np.unique(table.codes)) <= {0.0, 1.0}


def test_similar_phonemes_have_similar_codes():
    code = encoding.phoneme_table().code

    def distance(a, b):
        return np.abs(code(a) - code(b)).sum()

    assert distance("p", "b") == 1  # voicing only
    assert distance("p", "b") < distance("p", "i:")
    assert distance("t", "d") < distance("t", "m") < distance("t", "A:")
    assert distance("I", "i:") < distance("I", "k")


def test_paper_words():
    for word, phonemes in encoding.PAPER_LEXICON.items():
        assert encoding.pronounce(word) == phonemes
        code = encoding.encode_word(word).reshape(4, 20)
        assert code[len(phonemes) :].sum() == 0  # unused rows silent
        assert all(code[i].sum() > 0 for i in range(len(phonemes)))
    go, pick, lift = (encoding.encode_word(w).reshape(4, 20) for w in WORDS)
    np.testing.assert_array_equal(pick[1], lift[1])  # both /I/ second


def test_cmudict_words_map_to_british_phonemes():
    assert encoding.pronounce("stop") == ("s", "t", "Q", "p")
    assert encoding.pronounce("car") == ("k", "A:")  # non-rhotic
    assert encoding.encode_word("turn").shape == (80,)
    assert encoding.arpabet_to_sampa(["HH", "AE1", "P", "IY0"]) == ("h", "{", "p", "i")


def test_language_bad_input():
    with pytest.raises(ValueError, match="unknown phoneme 'xx'.*allowed"):
        encoding.encode_phonemes(["p", "xx"])
    with pytest.raises(ValueError, match="unknown word 'blorptangle'"):
        encoding.encode_word("blorptangle")
    with pytest.raises(ValueError, match="'elephant' has 7 phonemes.*at most 4"):
        encoding.encode_word("elephant")
    with pytest.raises(ValueError, match="1 to 4 phonemes"):
        encoding.encode_phonemes([])


def test_motor():
    np.testing.assert_array_equal(encoding.encode_motor("turn_left"), [0, 0, 0, 1])
    batch = encoding.encode_motor_batch(["forward", "backward"])
    np.testing.assert_array_equal(batch, [[1, 0, 0, 0], [0, 1, 0, 0]])
    np.testing.assert_array_equal(encoding.encode_motor_batch(np.array([2])), [[0, 0, 1, 0]])
    np.testing.assert_array_equal(
        encoding.motor_changed(encoding.encode_motor_batch([0, 0, 1, 1, 0])),
        [False, False, True, False, True],
    )
    with pytest.raises(ValueError, match="unknown directive 'left'.*forward, backward"):
        encoding.encode_motor("left")
    with pytest.raises(ValueError, match="index 4 out of range"):
        encoding.encode_motor_batch(np.array([4]))


def test_assemble_order_and_checks():
    vision = VisionEncoder(half_side_m=2.0).encode_batch([0.5], [0.0], [10.0])
    language = encoding.encode_words(["pick"])
    motor = encoding.encode_motor_batch(["backward"])
    z = encoding.assemble(vision, language, motor)
    assert z.shape == (1, 180)
    np.testing.assert_array_equal(z[0, encoding.VISION_SLICE], vision[0])
    np.testing.assert_array_equal(z[0, encoding.LANGUAGE_SLICE], language[0])
    np.testing.assert_array_equal(z[0, encoding.MOTOR_SLICE], motor[0])
    with pytest.raises(ValueError, match=r"shape \(n, 80\), got \(1, 79\)"):
        encoding.assemble(vision, language[:, :79], motor)
    with pytest.raises(ValueError, match="value 2.0 is out of range; allowed: \\[0, 1\\]"):
        encoding.assemble(vision, language * 2, motor)
    with pytest.raises(ValueError, match="finite"):
        encoding.assemble(vision * np.nan, language, motor)
    with pytest.raises(ValueError, match="same number of samples"):
        encoding.assemble(vision, encoding.encode_words(["go", "go"]), motor)
