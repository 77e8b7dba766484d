"""Saving and loading a fitted ``Associator`` as ``.npz`` (never pickled).

File layout (format version 1), every entry a plain numpy array:

- ``format``: the string ``"associator"``; ``format_version``: int.
- ``params``: JSON of ``Associator.get_params()`` (hyper-parameters, vocabulary included).
- ``vocabulary_codes``: (n_words, 80) language codes the vocabulary had when saved.
- ``W_bu``: (768, 180); ``W_td``: (180, 768); ``n_steps``: int.
- ``rng_state``: JSON of the generator's ``bit_generator.state``, so training resumes exactly.
- ``metadata``: JSON of a caller's dict (e.g. the vision encoder's arena), ``{}`` by default.

A :class:`~associator.hierarchy.HierarchicalAssociator` is stored the same way with ``format``
``"hierarchical_associator"``: the entries above hold its lower network, and these its own state:
``hierarchy_params`` (JSON of its own hyper-parameters, ``hierarchy.OWN_PARAMS``), ``word_links``
(n_words, n_hidden), ``word_transitions`` (n_words, n_words), ``word_unit_transitions`` (n_hidden,
n_words, n_words: the word transitions per previous lower winner; absent from files written before
it), the sparse lower-winner transitions
``transition_keys`` (m,) int64 (index in a flattened (n_words, n_hidden, n_hidden) table, strictly
increasing) and ``transition_counts`` (m,), and ``last_sample`` ([word, winner] of the last
training sample, -1 before any), so that training resumes exactly; optionally the word statistics
of ``count_word_statistics``: ``word_samples`` (n_words, n_hidden), ``word_pose_sums`` (n_words,
n_hidden, 4), ``word_pose_squares`` (n_words, n_hidden, 2), ``word_motor_counts`` (n_words,
n_hidden, 4), and ``word_transitions_into`` (n_hidden, n_words, n_words: the word transitions per
lower winner of the step they lead into; absent from files written before version 0.12.0, whose
``hierarchy_params`` also lack ``transition_winner``: they load with 'previous', the read-out they
were made with), and the sparse word transitions per pair of lower winners ``pair_transition_keys``
(m,) int64 (index in a flattened (n_hidden, n_hidden, n_words, n_words) table: previous winner,
current winner, previous word, word; strictly increasing) and ``pair_transition_counts`` (m,)
(absent from files written before version 0.14.0).

``load`` refuses, naming the entry, a file whose counts contradict each other, which no file that
``save`` wrote does: counts that are not whole, word links that do not add up to ``n_steps``,
transitions that do not match the links or each other, and word statistics with sums where there
are no samples, a heading longer than its sample count, a negative variance, or directive counts
that do not add up to the samples. The word links and the word statistics need not agree: the
links count the wake winners while the lower level learned, the statistics the recognition winners
of a frozen lower level, on whatever samples ``count_word_statistics`` was given.
"""

from __future__ import annotations

import json
import os
import zipfile

import numpy as np

from associator.encoding import N_LANGUAGE
from associator.hierarchy import OWN_PARAMS as HIERARCHY_PARAMS
from associator.hierarchy import HierarchicalAssociator
from associator.network import Associator

FORMAT = "associator"
HIERARCHICAL_FORMAT = "hierarchical_associator"
FORMAT_VERSION = 1
_BIT_GENERATORS = ("PCG64", "PCG64DXSM", "Philox", "SFC64", "MT19937")
_KEYS = (
    "format",
    "format_version",
    "params",
    "vocabulary_codes",
    "W_bu",
    "W_td",
    "n_steps",
    "rng_state",
    "metadata",
)
#: Optional entries of a hierarchical file: the word statistics, and the attributes they fill.
_STATISTICS = (
    ("word_samples", "word_samples_"),
    ("word_pose_sums", "word_pose_sums_"),
    ("word_pose_squares", "word_pose_squares_"),
    ("word_motor_counts", "word_motor_counts_"),
)
_HIERARCHY_KEYS = (
    "hierarchy_params",
    "word_links",
    "word_transitions",
    "transition_keys",
    "transition_counts",
    "last_sample",
)


def save(model, path, metadata: dict | None = None) -> str:
    """Writes a fitted model (an ``Associator`` or a ``HierarchicalAssociator``) to ``path``
    (``.npz``) and returns the path as a string."""
    if not hasattr(model, "n_steps_"):
        raise ValueError(f"this {type(model).__name__} is not fitted yet; call fit first")
    path = os.fspath(path)
    extra = {}
    if isinstance(model, HierarchicalAssociator):
        own = {name: getattr(model, name) for name in HIERARCHY_PARAMS}
        extra = {
            "hierarchy_params": np.array(json.dumps(own)),
            "word_links": np.asarray(model.word_links_, dtype=float),
            "word_transitions": np.asarray(model.word_transitions_, dtype=float),
            "transition_keys": np.asarray(model.transition_keys_, dtype=np.int64),
            "transition_counts": np.asarray(model.transition_counts_, dtype=float),
            "last_sample": np.array([model.last_word_, model.last_winner_], dtype=np.int64),
        }
        if hasattr(model, "word_unit_transitions_"):  # networks loaded from older files lack it
            extra["word_unit_transitions"] = np.asarray(model.word_unit_transitions_, dtype=float)
        if model.has_word_statistics_:
            extra.update(
                {key: np.asarray(getattr(model, attr), dtype=float) for key, attr in _STATISTICS}
            )
            if hasattr(model, "word_transitions_into_"):  # files before version 0.12.0 lack it
                extra["word_transitions_into"] = np.asarray(
                    model.word_transitions_into_, dtype=float
                )
            if hasattr(model, "pair_transition_keys_"):  # files before version 0.14.0 lack it
                extra["pair_transition_keys"] = np.asarray(
                    model.pair_transition_keys_, dtype=np.int64
                )
                extra["pair_transition_counts"] = np.asarray(
                    model.pair_transition_counts_, dtype=float
                )
        model = model.lower_
    params = model.get_params()
    state = model.rng_.bit_generator.state
    arrays = {
        "format": np.array(HIERARCHICAL_FORMAT if extra else FORMAT),
        "format_version": np.array(FORMAT_VERSION),
        "params": np.array(json.dumps(params)),
        "vocabulary_codes": np.asarray(model.vocabulary_codes_),
        "W_bu": np.ascontiguousarray(model.W_bu_),
        "W_td": np.ascontiguousarray(model.W_td_),
        "n_steps": np.array(model.n_steps_, dtype=np.int64),
        "rng_state": np.array(json.dumps(state)),
        "metadata": np.array(json.dumps(metadata or {})),
        **extra,
    }
    with open(path, "wb") as handle:
        np.savez(handle, **arrays)
    return path


def _fail(path, why: str):
    raise ValueError(f"{path}: not a valid associator file: {why}")


def load_metadata(path) -> dict:
    """Returns the metadata dict stored with a model."""
    return _read(path)[1]


def load(path):
    """Reads a model written by ``save`` (an ``Associator`` or a ``HierarchicalAssociator``, as
    saved); raises ValueError for a corrupt or mismatched file."""
    return _read(path)[0]


def _read(path):
    path = os.fspath(path)
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):  # a .npy file holds one bare array
            _fail(path, f"not an .npz archive (one {type(loaded).__name__})")
        with loaded as archive:
            keys = _KEYS
            if "format" in archive.files and str(archive["format"]) == HIERARCHICAL_FORMAT:
                keys = _KEYS + _HIERARCHY_KEYS
            missing = [key for key in keys if key not in archive.files]
            if missing:
                _fail(path, f"missing entries {missing}")
            data = {key: archive[key] for key in keys}
            present = [key for key, _ in _STATISTICS if key in archive.files]
            if present and len(present) != len(_STATISTICS):
                _fail(path, f"word statistics incomplete: has only {present}")
            data.update({key: archive[key] for key in present})
            for key in (
                "word_unit_transitions",
                "word_transitions_into",
                "pair_transition_keys",
                "pair_transition_counts",
            ):
                if key in archive.files:  # files written before them lack them
                    data[key] = archive[key]
    except ValueError as error:
        if "not a valid associator file" in str(error):
            raise
        _fail(path, f"unreadable ({error})")
    except (OSError, EOFError, zipfile.BadZipFile, KeyError) as error:
        _fail(path, f"unreadable ({type(error).__name__}: {error})")
    if str(data["format"]) not in (FORMAT, HIERARCHICAL_FORMAT):
        _fail(
            path,
            f"format is {str(data['format'])!r}, expected {FORMAT!r} or {HIERARCHICAL_FORMAT!r}",
        )
    version = int(data["format_version"])
    if version != FORMAT_VERSION:
        _fail(path, f"format_version {version}; this code reads version {FORMAT_VERSION}")
    try:
        params = json.loads(str(data["params"]))
        state = json.loads(str(data["rng_state"]))
        metadata = json.loads(str(data["metadata"]))
    except json.JSONDecodeError as error:
        _fail(path, f"bad JSON entry ({error})")
    params["hidden_shape"] = tuple(params["hidden_shape"])
    params["vocabulary"] = tuple(params["vocabulary"])
    if state.get("bit_generator") not in _BIT_GENERATORS:
        _fail(
            path,
            f"unknown bit generator {state.get('bit_generator')!r}; allowed: {_BIT_GENERATORS}",
        )
    try:
        generator = np.random.Generator(getattr(np.random, state["bit_generator"])())
        generator.bit_generator.state = state
    except (TypeError, ValueError, KeyError) as error:
        _fail(path, f"bad rng state ({error})")
    try:
        model = Associator.from_state(
            params, data["W_bu"], data["W_td"], int(data["n_steps"]), generator
        )
    except ValueError as error:
        _fail(path, str(error))
    codes = data["vocabulary_codes"]
    if codes.shape != (len(model.vocabulary), N_LANGUAGE) or not np.array_equal(
        codes, model.vocabulary_codes_
    ):
        _fail(path, "the vocabulary's language codes differ from this package's phoneme table")
    if str(data["format"]) == HIERARCHICAL_FORMAT:
        model = _hierarchical(path, model, data)
    return model, metadata


def _hierarchical(path, lower: Associator, data) -> HierarchicalAssociator:
    try:
        own = json.loads(str(data["hierarchy_params"]))
        own.setdefault("perform_readout", "winner")  # saved before version 0.5.0
        own.setdefault("pose_heading_bins", 1)  # saved before version 0.6.0
        own.setdefault("pose_tail_dof", 0.0)  # saved before version 0.8.0: Gaussian components
        own.setdefault("transition_winner", "previous")  # saved before version 0.12.0
        own.setdefault("pair_transition_prior", 1.0)  # saved before version 0.14.0 (unused there)
        unfitted_lower = Associator(**lower.get_params())
        model = HierarchicalAssociator(lower=unfitted_lower, **own)
        model.validate_params()
    except (json.JSONDecodeError, TypeError, ValueError) as error:
        _fail(path, f"bad hierarchy parameters ({error})")
    links = data["word_links"]
    if links.shape != (len(lower.vocabulary), lower.n_hidden):
        _fail(
            path,
            f"word_links has shape {links.shape}, expected "
            f"({len(lower.vocabulary)}, {lower.n_hidden})",
        )
    if not np.all(np.isfinite(links)) or np.any(links < 0):
        _fail(path, "word_links has negative or non-finite values")
    n_words, n_hidden = len(lower.vocabulary), lower.n_hidden
    words = data["word_transitions"]
    if words.shape != (n_words, n_words):
        _fail(path, f"word_transitions has shape {words.shape}, expected ({n_words}, {n_words})")
    keys, counts = data["transition_keys"], data["transition_counts"]
    if keys.ndim != 1 or counts.shape != keys.shape or keys.dtype != np.int64:
        _fail(
            path,
            f"transition_keys {keys.dtype} {keys.shape} and transition_counts {counts.shape} "
            "must be 1-D of one length, the keys int64",
        )
    if len(keys) and (
        keys[0] < 0 or keys[-1] >= n_words * n_hidden * n_hidden or np.any(np.diff(keys) <= 0)
    ):
        _fail(
            path,
            f"transition_keys must increase strictly within [0, {n_words * n_hidden * n_hidden})",
        )
    for name, values in (("word_transitions", words), ("transition_counts", counts)):
        if not np.all(np.isfinite(values)) or np.any(values < 0):
            _fail(path, f"{name} has negative or non-finite values")
    last = data["last_sample"]
    if (
        last.shape != (2,)
        or not -1 <= last[0] < n_words
        or not -1 <= last[1] < n_hidden
        or (last[0] < 0) != (last[1] < 0)
    ):
        _fail(
            path,
            f"last_sample {last!r} must be [word, winner], both -1 or word < {n_words} and "
            f"winner < {n_hidden}",
        )
    _counts_agree(path, lower, links, words, keys, counts, last)
    model.lower_ = lower
    model.word_links_ = np.array(links, dtype=float)
    model.word_transitions_ = np.array(words, dtype=float)
    model.transition_keys_ = np.array(keys)
    model.transition_counts_ = np.array(counts, dtype=float)
    model.last_word_, model.last_winner_ = int(last[0]), int(last[1])
    if "word_unit_transitions" in data:
        after = data["word_unit_transitions"]
        _check_word_transition_table(path, "word_unit_transitions", after, n_hidden, n_words)
        if not np.array_equal(after.sum(axis=0), words):
            _fail(path, "word_unit_transitions do not add up to word_transitions")
        model.word_unit_transitions_ = np.array(after, dtype=float)
    if _STATISTICS[0][0] in data:
        _word_statistics(path, model, data)
    return model


def _check_word_transition_table(path, key: str, table, n_hidden: int, n_words: int) -> None:
    """Fails unless ``table`` is word transitions per lower winner: (n_hidden, n_words, n_words)
    whole, finite, non-negative counts."""
    if table.shape != (n_hidden, n_words, n_words):
        _fail(path, f"{key} has shape {table.shape}, expected ({n_hidden}, {n_words}, {n_words})")
    if not np.all(np.isfinite(table)) or np.any(table < 0):
        _fail(path, f"{key} has negative or non-finite values")
    _whole(path, key, table)


def _whole(path, key: str, values: np.ndarray) -> None:
    """Fails unless ``values`` are whole numbers: counts, each sample adding one."""
    if np.any(values != np.round(values)):
        _fail(path, f"{key} has non-whole counts (each sample adds one)")


def _counts_agree(path, lower: Associator, links, words, keys, counts, last) -> None:
    """Fails unless the word layer's counts are those of one training stream: each sample adds one
    link (``n_steps`` in all), each sample after the first one transition, counted once in
    ``word_transitions`` (from its previous word) and once in the lower-winner transitions (under
    its word), and the last sample's link exists."""
    if last.dtype.kind not in "iu":
        _fail(path, f"last_sample must hold integers, got {last.dtype}")
    for key, values in (
        ("word_links", links),
        ("word_transitions", words),
        ("transition_counts", counts),
    ):
        _whole(path, key, values)
    n_steps = lower.n_steps_
    if links.sum() != n_steps:
        _fail(path, f"word_links count {links.sum():g} samples, but n_steps is {n_steps}")
    if (last[0] < 0) != (n_steps == 0):
        _fail(path, f"last_sample {last.tolist()} does not fit n_steps {n_steps}")
    if n_steps == 0:
        return
    if links[last[0], last[1]] < 1:
        _fail(path, f"last_sample {last.tolist()} has no count in word_links")
    n_words, n_hidden = words.shape[0], links.shape[1]
    leaving = links.sum(axis=1) - (np.arange(n_words) == last[0])
    if not np.array_equal(words.sum(axis=1), leaving):
        _fail(
            path,
            f"word_transitions leave the words {words.sum(axis=1).tolist()} times, but word_links "
            f"count {leaving.tolist()} samples followed by another",
        )
    under_word = np.bincount(keys // (n_hidden * n_hidden), weights=counts, minlength=n_words)
    if not np.array_equal(under_word, words.sum(axis=0)):
        _fail(
            path,
            f"transition_counts hold {under_word.tolist()} transitions per word, but "
            f"word_transitions {words.sum(axis=0).tolist()}",
        )


def _word_statistics(path, model: HierarchicalAssociator, data) -> None:
    """Checks and sets the optional word statistics (``count_word_statistics``)."""
    n_words = len(model.vocabulary)
    n_components = model.lower_.n_hidden * int(model.pose_heading_bins)  # unit x heading sector
    shapes = {
        "word_samples": (n_words, n_components),
        "word_pose_sums": (n_words, n_components, 4),
        "word_pose_squares": (n_words, n_components, 2),
        "word_motor_counts": (n_words, n_components, 4),
    }
    for key, _ in _STATISTICS:
        values = data[key]
        if values.shape != shapes[key]:
            _fail(path, f"{key} has shape {values.shape}, expected {shapes[key]}")
        if not np.all(np.isfinite(values)):
            _fail(path, f"{key} has non-finite values")
        if key != "word_pose_sums" and np.any(values < 0):
            _fail(path, f"{key} has negative values")
    samples, sums, squares = data["word_samples"], data["word_pose_sums"], data["word_pose_squares"]
    for key in ("word_samples", "word_motor_counts"):
        _whole(path, key, data[key])

    def cell(where: np.ndarray) -> str:
        word, component = np.argwhere(where)[0]
        return f"(word {model.vocabulary[word]!r}, component {component})"

    wrong = data["word_motor_counts"].sum(axis=2) != samples
    if np.any(wrong):
        _fail(path, f"word_motor_counts do not add up to word_samples at {cell(wrong)}")
    empty = samples == 0
    for key, values in (("word_pose_sums", sums), ("word_pose_squares", squares)):
        wrong = empty & np.any(values != 0, axis=2)
        if np.any(wrong):
            _fail(path, f"{key} is not zero at {cell(wrong)}, where word_samples counts no sample")
    # The heading's unit vectors add up to at most one per sample; the squares of the x and y bump
    # centres to at least their sum squared over the samples (Cauchy-Schwarz). Both within
    # rounding: a relative 1e-6, above a double's worst summation error (n x 1.1e-16) for up to
    # a billion samples.
    heading = np.hypot(sums[..., 2], sums[..., 3])
    wrong = heading > samples * (1 + 1e-6)
    if np.any(wrong):
        _fail(
            path,
            f"word_pose_sums has a heading vector longer than its sample count at {cell(wrong)}",
        )
    safe = np.maximum(samples, 1.0)[..., None]
    wrong = np.any(squares - sums[..., :2] ** 2 / safe < -1e-6 * squares - 1e-12, axis=2)
    if np.any(wrong):
        _fail(
            path,
            f"word_pose_squares is smaller than word_pose_sums squared over word_samples (a "
            f"negative variance) at {cell(wrong)}",
        )
    for key, attr in _STATISTICS:
        setattr(model, attr, np.array(data[key], dtype=float))
    if "word_transitions_into" in data:
        _transitions_into(path, model, data["word_transitions_into"], samples)
    if "pair_transition_keys" in data or "pair_transition_counts" in data:
        _pair_transitions(path, model, data)


def _transitions_into(path, model: HierarchicalAssociator, into: np.ndarray, samples) -> None:
    """Checks and sets the word transitions per lower winner of the step they lead into: whole,
    and at each winner and word at most the samples the word statistics count there (each
    sample after the first of a counted piece adds one)."""
    n_words, n_hidden = len(model.vocabulary), model.lower_.n_hidden
    _check_word_transition_table(path, "word_transitions_into", into, n_hidden, n_words)
    per_unit = samples.reshape(n_words, n_hidden, -1).sum(axis=2)  # summed over heading sectors
    if np.any(into.sum(axis=1).T > per_unit):
        _fail(path, "word_transitions_into count more samples than word_samples at some winner")
    model.word_transitions_into_ = np.array(into, dtype=float)
    model.statistics_last_word_ = -1  # a later count starts a new piece
    model.statistics_last_winner_ = -1


def _pair_transitions(path, model: HierarchicalAssociator, data) -> None:
    """Checks and sets the sparse word transitions per pair of lower winners: both entries, keys
    strictly increasing within the table, whole positive counts, and per current winner and pair
    of words at most what ``word_transitions_into`` counts (the same steps, maybe fewer pieces)."""
    if not ("pair_transition_keys" in data and "pair_transition_counts" in data):
        _fail(path, "pair_transition_keys and pair_transition_counts come together")
    if not hasattr(model, "word_transitions_into_"):
        _fail(path, "pair_transition_keys without word_transitions_into")
    keys, counts = data["pair_transition_keys"], data["pair_transition_counts"]
    n_words, n_hidden = len(model.vocabulary), model.lower_.n_hidden
    size = n_hidden * n_hidden * n_words * n_words
    if keys.ndim != 1 or counts.shape != keys.shape or keys.dtype != np.int64:
        _fail(
            path,
            f"pair_transition_keys {keys.dtype} {keys.shape} and pair_transition_counts "
            f"{counts.shape} must be 1-D of one length, the keys int64",
        )
    if len(keys) and (keys[0] < 0 or keys[-1] >= size or np.any(np.diff(keys) <= 0)):
        _fail(path, f"pair_transition_keys must increase strictly within [0, {size})")
    if not np.all(np.isfinite(counts)) or np.any(counts <= 0):
        _fail(path, "pair_transition_counts has non-positive or non-finite values")
    _whole(path, "pair_transition_counts", counts)
    summed = np.zeros_like(model.word_transitions_into_)
    current, words = (keys // (n_words * n_words)) % n_hidden, keys % (n_words * n_words)
    np.add.at(summed, (current, words // n_words, words % n_words), counts)
    if np.any(summed > model.word_transitions_into_):
        _fail(path, "pair_transition_counts count more than word_transitions_into at some winner")
    model.pair_transition_keys_ = np.array(keys)
    model.pair_transition_counts_ = np.array(counts, dtype=float)
