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
(n_words, n_hidden), ``word_transitions`` (n_words, n_words), the sparse lower-winner transitions
``transition_keys`` (m,) int64 (index in a flattened (n_words, n_hidden, n_hidden) table, strictly
increasing) and ``transition_counts`` (m,), and ``last_sample`` ([word, winner] of the last
training sample, -1 before any), so that training resumes exactly; optionally the word statistics
of ``count_word_statistics``: ``word_samples`` (n_words, n_hidden), ``word_pose_sums`` (n_words,
n_hidden, 4), ``word_pose_squares`` (n_words, n_hidden, 2), ``word_motor_counts`` (n_words,
n_hidden, 4).
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
        if model.has_word_statistics_:
            extra.update(
                {key: np.asarray(getattr(model, attr), dtype=float) for key, attr in _STATISTICS}
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
        with np.load(path, allow_pickle=False) as archive:
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
    model.lower_ = lower
    model.word_links_ = np.array(links, dtype=float)
    model.word_transitions_ = np.array(words, dtype=float)
    model.transition_keys_ = np.array(keys)
    model.transition_counts_ = np.array(counts, dtype=float)
    model.last_word_, model.last_winner_ = int(last[0]), int(last[1])
    if _STATISTICS[0][0] in data:
        _word_statistics(path, model, data)
    return model


def _word_statistics(path, model: HierarchicalAssociator, data) -> None:
    """Checks and sets the optional word statistics (``count_word_statistics``)."""
    n_words, n_hidden = len(model.vocabulary), model.lower_.n_hidden
    shapes = {
        "word_samples": (n_words, n_hidden),
        "word_pose_sums": (n_words, n_hidden, 4),
        "word_pose_squares": (n_words, n_hidden, 2),
        "word_motor_counts": (n_words, n_hidden, 4),
    }
    for key, _ in _STATISTICS:
        values = data[key]
        if values.shape != shapes[key]:
            _fail(path, f"{key} has shape {values.shape}, expected {shapes[key]}")
        if not np.all(np.isfinite(values)):
            _fail(path, f"{key} has non-finite values")
        if key != "word_pose_sums" and np.any(values < 0):
            _fail(path, f"{key} has negative values")
    if not np.array_equal(data["word_motor_counts"].sum(axis=2), data["word_samples"]):
        _fail(path, "word_motor_counts do not add up to word_samples")
    for key, attr in _STATISTICS:
        setattr(model, attr, np.array(data[key], dtype=float))
