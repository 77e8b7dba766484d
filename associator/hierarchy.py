"""A two-level associator: the paper's network on vision and motor, and a word layer above it.

The lower level is the paper's :class:`~associator.network.Associator`, trained with the language
area silent and the motor area weighted by ``motor_gain``; the word layer links each vocabulary word
to the lower winners by Hebbian counts, and counts word and winner transitions for recognition over
time. ``docs/associator.md`` (the hierarchical associator) explains the read-outs, why the
hierarchy, and the measurements behind the defaults.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from associator import encoding
from associator.encoding import DIRECTIVES, N_MOTOR, N_PHI, N_VISION
from associator.network import (
    Associator,
    BatchPerformance,
    BatchRecognition,
    Performance,
    Recognition,
    check_motor_changed,
    check_motor_weight,
    word_indices,
)

#: Hyper-parameters of the word layer and the motor gain; everything else is the lower network's.
OWN_PARAMS = (
    "motor_gain",
    "link_floor",
    "word_bias",
    "transition_prior",
    "word_transition_floor",
    "pose_weight",
    "pose_width_floor",
    "min_word_samples",
    "unit_transition_prior",
    "pose_evidence",
    "perform_temperature",
    "perform_readout",
    "pose_heading_bins",
    "pose_tail_dof",
    "transition_winner",
    "pair_transition_prior",
)

#: Hyper-parameters that act only when performing (``perform_batch``): they change no training,
#: count or recognition, so networks learnt with other values of them can perform with these.
PERFORM_ONLY_PARAMS = (
    "word_bias",
    "pose_weight",
    "perform_temperature",
    "perform_readout",
    "pose_tail_dof",
)

#: How performing reads the motor directive out (``perform_readout``).
PERFORM_READOUTS = ("posterior", "winner")

#: Which lower winner recognition over time conditions the word transitions on
#: (``transition_winner``).
TRANSITION_WINNERS = ("current", "previous", "pair")

#: Hyper-parameters that are names, checked against their allowed values instead.
_NOT_NUMBERS = ("perform_readout", "transition_winner")

#: Hyper-parameters for which 0 is a setting (switches a read-out off), not an error.
_MAY_BE_ZERO = ("perform_temperature", "pose_tail_dof")

#: The word layer's pose and motor statistics (``count_word_statistics``), counted with the lower
#: level frozen: further training of the lower level drops them.
_WORD_STATISTICS = (
    "word_samples_",
    "word_pose_sums_",
    "word_pose_squares_",
    "word_motor_counts_",
    "word_transitions_into_",
    "pair_transition_keys_",
    "pair_transition_counts_",
    "statistics_last_word_",
    "statistics_last_winner_",
)

#: The learned state, dropped by ``fit`` before it starts afresh.
_LEARNED = (
    "lower_",
    "word_links_",
    "word_transitions_",
    "word_unit_transitions_",
    "transition_keys_",
    "transition_counts_",
    "last_word_",
    "last_winner_",
    *_WORD_STATISTICS,
)


#: Samples performed at a time in ``perform_batch`` with one heading sector (its work arrays are
#: chunk x n_hidden; with B sectors it takes chunk / B samples at a time).
_PERFORM_CHUNK = 4096


def _pose_features(vision: np.ndarray) -> np.ndarray:
    """Returns (n, 4): the x and y bump centres of vision codes in units, and the heading's unit
    vector (cos, sin)."""
    centres = encoding.vision_code_centres(vision)
    angle = centres[:, 2] * (2 * np.pi / N_PHI)
    return np.stack([centres[:, 0], centres[:, 1], np.cos(angle), np.sin(angle)], axis=1)


def heading_sectors(vision: np.ndarray, bins: int) -> np.ndarray:
    """Returns (n,) int: the sector, of ``bins`` equal ones around the circle (sector 0 centred on
    0 deg), that the heading of each vision code (n, 96) lies in."""
    centres = encoding.vision_code_centres(vision)[:, 2]
    width = N_PHI / bins
    return (np.floor((centres - N_PHI / 2) / width + 0.5).astype(np.int64)) % bins


def _word_list(words, vocabulary) -> list:
    """Returns ``words`` (a sequence of names) as a list; ValueError for anything that is not a
    sequence of strings (this network takes words, never language codes)."""
    try:
        names = list(words)
    except TypeError:
        names = [words]
    others = [name for name in names if not isinstance(name, str)]
    if others:
        raise ValueError(
            f"words must be one word or a sequence of words of the vocabulary {tuple(vocabulary)}, "
            f"got {type(others[0]).__name__} {repr(others[0]):.60}"
        )
    return names


class SequenceState(NamedTuple):
    """Where recognition over time stands after a sample, to continue with the next ones.

    Attributes:
      posterior: (n_words,) the belief over the words, summing to one.
      last_winner: the lower winner of the last sample, -1 if it was not seen.
    """

    posterior: np.ndarray
    last_winner: int


class SequenceRecognition(NamedTuple):
    """Recognition of ``n`` consecutive samples over time: ``words`` (n,) str, the word of highest
    belief at each step; ``scores`` (n, n_words) the log belief ``log p(word_t | samples up to
    t)``; ``winners`` (n,) the lower winners (-1 on samples not seen); ``state`` to pass to the
    next call for the samples that follow."""

    words: np.ndarray
    scores: np.ndarray
    winners: np.ndarray
    state: SequenceState


class HierarchicalAssociator:
    """The two-level associator, in the scikit-learn shape of :class:`Associator`.

    Learning: each sample trains the lower network on vision and ``motor_gain`` x motor (language
    silent) and adds one to the link between its heard word and its wake winner ``k``, so a word
    unit's normalised links are ``p(k | word)``. Recognition takes the word under which the lower
    winner is most likely; performance lets the word bias the lower competition.

    Parameters
    ----------
    lower : Associator or None
        The lower network's hyper-parameters and ``rng``, as an unfitted :class:`Associator`
        (``fit`` trains a fresh one with them and leaves this object as it is). None (default):
        ``Associator()``, the paper's defaults.
    motor_gain : float
        Factor on the motor area at the lower level, in training and read-outs (default 3).
    link_floor : float
        Added to every word-to-winner link (a count) before normalising, so that a winner never
        seen with a word is unlikely for it, not impossible (default 1e-3).
    word_bias : float
        Weight of ``log p(k | word)`` against the vision cosine in performance (default 0.05).
    transition_prior : float
        Weight of ``p(k | word)`` added to the counts of lower-winner transitions in
        ``p(k_t | k_(t-1), word)``, a back-off for transitions seldom or never seen (default 1).
    word_transition_floor : float
        Added to every count of word-to-word transitions before normalising, so that a transition
        never seen (e.g. 'pick' back to 'go') stays possible (default 1).
    pose_weight : float
        Weight of the counted word-and-unit pose log-likelihood in performance (default 0.03).
    pose_width_floor : float
        Least spread of a counted component along each pose coordinate, in units of the vision
        code (default 0.5).
    min_word_samples : int
        Components counted fewer times than this under their word do not compete in performance
        (default 20).
    unit_transition_prior : float
        Recognition over time takes the word transitions where they happened,
        ``p(word_t | word_(t-1), k_(t-1))``, counted per previous lower winner and backed off to
        ``p(word_t | word_(t-1))`` with this weight, in samples (default 10).
    pose_evidence : float
        Once ``count_word_statistics`` has counted, recognition over time also weighs how well the
        pose fits each word's component at the winner: its evidence is multiplied by
        ``N(pose | word, k) ** pose_evidence`` (default 0.1).
    perform_temperature : float
        With ``perform_readout = "winner"`` and the counted components: 0 (default) drives with
        the winner's ``p(directive | k, word)``; above 0, with their mixture over every counted
        component, each weighted by ``softmax(activation / perform_temperature)`` (0 or more).
    perform_readout : str
        'posterior' (default): once ``count_word_statistics`` has counted, the motor output is
        ``sum_k p(k | pose, word) p(directive | k, word)``, each counted component weighted by its
        posterior ``n_k N(pose | word, k)`` normalised (an interpolation between units: each unit
        holds one directive, so the winner alone switches between them). 'winner': the unit that
        wins the biased competition below, as up to version 0.4.0.
    pose_heading_bins : int
        The posterior read-out's components split each word-and-unit component by the heading
        sector its samples were in (this many equal sectors, one centred on 0 deg; 1: no split).
        A unit that won every turn of a word in place then gives one component per heading,
        each where the teacher turned at that heading, instead of one wide blob that claims
        every pose near it (default 24, the heading code's units; recognition keeps the unit's
        whole component).
    pose_tail_dof : float
        The posterior read-out's components: 0 Gaussian; above 0, Student-t with this many
        degrees of freedom, ``- (dof + 3) / 2 log(1 + d^2 / dof)`` in place of ``- d^2 / 2`` for
        the squared standardised distance ``d^2`` (default 10; files saved before version 0.8.0
        load with 0). Heavier tails keep a wide component from taking over the mixture far from
        every mean (0 or more; recognition is unchanged).
    transition_winner : str
        Recognition over time: 'pair' (default since version 0.14.0) takes the word transitions
        counted per pair of lower winners, of the step before and of the step they lead into,
        ``p(word_t | word_(t-1), k_(t-1), k_t)`` (counted by ``count_word_statistics``: a word
        often begins where one unit follows another, which the unit it enters alone mixes with
        every other way in), backed off to 'current' with ``pair_transition_prior``; 'current'
        (versions 0.12.0-0.13.0) per lower winner of the step they lead into, ``p(word_t |
        word_(t-1), k_t)`` (also counted by ``count_word_statistics``): the teacher switches where
        it is and acts on the new word at once, so the switch shows in the winner of that step;
        'previous' per winner of the step before, ``p(word_t | word_(t-1), k_(t-1))`` (counted
        while training; up to version 0.11.0, and files saved before 0.12.0 load with it). The
        last two backed off to ``p(word_t | word_(t-1))`` with ``unit_transition_prior``. Without
        the counts of 'pair' (files saved before 0.14.0) the read-out takes 'current', without
        those of 'current' (not counted yet) 'previous'.
    pair_transition_prior : float
        With ``transition_winner = "pair"``: the weight, in samples, of 'current''s transitions
        in each pair's (default 1).
    """

    def __init__(
        self,
        *,
        lower: Associator | None = None,
        motor_gain: float = 3.0,
        link_floor: float = 1e-3,
        word_bias: float = 0.05,
        transition_prior: float = 1.0,
        word_transition_floor: float = 1.0,
        pose_weight: float = 0.03,
        pose_width_floor: float = 0.5,
        min_word_samples: int = 20,
        unit_transition_prior: float = 10.0,
        pose_evidence: float = 0.1,
        perform_temperature: float = 0.0,
        perform_readout: str = "posterior",
        pose_heading_bins: int = 24,
        pose_tail_dof: float = 10.0,
        transition_winner: str = "pair",
        pair_transition_prior: float = 1.0,
    ):
        self.lower = lower
        self.motor_gain = motor_gain
        self.link_floor = link_floor
        self.word_bias = word_bias
        self.transition_prior = transition_prior
        self.word_transition_floor = word_transition_floor
        self.pose_weight = pose_weight
        self.pose_width_floor = pose_width_floor
        self.min_word_samples = min_word_samples
        self.unit_transition_prior = unit_transition_prior
        self.pose_evidence = pose_evidence
        self.perform_temperature = perform_temperature
        self.perform_readout = perform_readout
        self.pose_heading_bins = pose_heading_bins
        self.pose_tail_dof = pose_tail_dof
        self.transition_winner = transition_winner
        self.pair_transition_prior = pair_transition_prior

    def _lower_estimator(self) -> Associator:
        """Returns ``lower``, or the paper's ``Associator()`` for None; ValueError for others."""
        if self.lower is None:
            return Associator()
        if not isinstance(self.lower, Associator):
            raise ValueError(
                f"lower must be an Associator or None, got {type(self.lower).__name__}"
            )
        return self.lower

    def _fresh_lower(self) -> Associator:
        """Returns an unfitted Associator with ``lower``'s hyper-parameters and ``rng`` (the same
        seed or generator object), as scikit-learn's ``clone`` would."""
        template = self._lower_estimator()
        params = {name: getattr(template, name) for name in template.get_params()}
        return Associator(**params, rng=template.rng)

    def get_params(self) -> dict:
        """Returns the hyper-parameters as one flat dict: the lower network's (``rng`` excluded)
        and the hierarchy's own (``OWN_PARAMS``)."""
        params = self._lower_estimator().get_params()
        params.update(
            motor_gain=float(self.motor_gain),
            link_floor=float(self.link_floor),
            word_bias=float(self.word_bias),
            transition_prior=float(self.transition_prior),
            word_transition_floor=float(self.word_transition_floor),
            pose_weight=float(self.pose_weight),
            pose_width_floor=float(self.pose_width_floor),
            min_word_samples=int(self.min_word_samples),
            unit_transition_prior=float(self.unit_transition_prior),
            pose_evidence=float(self.pose_evidence),
            perform_temperature=float(self.perform_temperature),
            perform_readout=str(self.perform_readout),
            pose_heading_bins=int(self.pose_heading_bins),
            pose_tail_dof=float(self.pose_tail_dof),
            transition_winner=str(self.transition_winner),
            pair_transition_prior=float(self.pair_transition_prior),
        )
        return params

    @property
    def vocabulary(self) -> tuple[str, ...]:
        """The words the network knows: the lower network's ``vocabulary``."""
        return tuple(self._lower_estimator().vocabulary)

    def validate_params(self) -> None:
        """Raises ValueError naming the first bad hyper-parameter, the lower network's included."""
        self._lower_estimator().validate_params()
        if self.perform_readout not in PERFORM_READOUTS:
            raise ValueError(
                f"unknown perform_readout {self.perform_readout!r}; allowed: "
                f"{', '.join(PERFORM_READOUTS)}"
            )
        if self.transition_winner not in TRANSITION_WINNERS:
            raise ValueError(
                f"unknown transition_winner {self.transition_winner!r}; allowed: "
                f"{', '.join(TRANSITION_WINNERS)}"
            )
        bins = self.pose_heading_bins
        number = isinstance(bins, (int, float, np.integer, np.floating)) and not isinstance(
            bins, bool
        )
        if not (number and np.isfinite(bins) and bins == int(bins) and 1 <= bins <= N_PHI):
            raise ValueError(
                f"pose_heading_bins must be a whole number in [1, {N_PHI}], got {bins!r}"
            )
        for name in OWN_PARAMS:
            if name in _NOT_NUMBERS:
                continue
            value = getattr(self, name)
            if name in _MAY_BE_ZERO:
                if not (isinstance(value, (int, float)) and np.isfinite(value) and value >= 0):
                    raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
            elif not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        if float(self.min_word_samples) != int(self.min_word_samples):
            raise ValueError(
                f"min_word_samples must be a positive whole number, got {self.min_word_samples!r}"
            )

    def _check_fitted(self) -> None:
        if not hasattr(self, "lower_"):
            raise ValueError("this HierarchicalAssociator is not fitted yet; call fit first")

    @property
    def n_steps_(self) -> int:
        """Training samples seen (absent before fitting, as learned attributes are)."""
        if not hasattr(self, "lower_"):
            raise AttributeError("n_steps_: not fitted yet")
        return self.lower_.n_steps_

    # ------------------------------------------------------------------------------------------
    # Training

    def fit(self, vision, language, motor, motor_changed=None) -> HierarchicalAssociator:
        """Starts afresh and trains on a stream; see ``partial_fit``. Returns self."""
        for name in _LEARNED:
            self.__dict__.pop(name, None)
        return self.partial_fit(vision, language, motor, motor_changed)

    def partial_fit(self, vision, language, motor, motor_changed=None) -> HierarchicalAssociator:
        """Trains both levels on ``n`` consecutive samples (shapes as for
        :meth:`Associator.partial_fit`); the heard word of each sample is its language code's
        nearest vocabulary word."""
        self.validate_params()
        z = encoding.assemble(vision, language, motor)
        n = z.shape[0]
        changed = check_motor_changed(motor_changed, n)
        if not hasattr(self, "lower_"):
            n_words = len(self.vocabulary)
            self.lower_ = self._fresh_lower()
            self.word_links_ = np.zeros((n_words, self.lower_.n_hidden))
            self.word_transitions_ = np.zeros((n_words, n_words))
            self.word_unit_transitions_ = np.zeros((self.lower_.n_hidden, n_words, n_words))
            self.transition_keys_ = np.zeros(0, np.int64)
            self.transition_counts_ = np.zeros(0)
            self.last_word_, self.last_winner_ = -1, -1
        if not hasattr(self, "word_unit_transitions_"):
            raise ValueError(
                "this network was saved before the word transitions per lower winner were "
                "counted: it recognises and performs, but cannot learn on; fit it anew"
            )
        if n == 0:
            return self
        for name in _WORD_STATISTICS:  # counted on the lower level as it was: now stale
            self.__dict__.pop(name, None)
        self._statistics_changed()
        words = self._heard_words(z[:, encoding.LANGUAGE_SLICE])
        z[:, encoding.LANGUAGE_SLICE] = 0.0  # the lower level never hears language
        z[:, encoding.MOTOR_SLICE] *= self.motor_gain
        winners = self.lower_.learn_inputs(z, changed)  # each sample's wake winner
        np.add.at(self.word_links_, (words, winners), 1.0)
        # Transitions from the previous sample (the last of the previous call included).
        previous_words = np.concatenate([[self.last_word_], words[:-1]])
        previous_winners = np.concatenate([[self.last_winner_], winners[:-1]])
        known = previous_words >= 0
        np.add.at(self.word_transitions_, (previous_words[known], words[known]), 1.0)
        np.add.at(
            self.word_unit_transitions_,
            (previous_winners[known], previous_words[known], words[known]),
            1.0,
        )
        self._count_transitions(
            self._transition_key(words[known], previous_winners[known], winners[known])
        )
        self.last_word_, self.last_winner_ = int(words[-1]), int(winners[-1])
        return self

    def _transition_key(self, word, previous, current) -> np.ndarray:
        """Returns the index of (word, previous winner, current winner) in a flattened
        (n_words, n_hidden, n_hidden) table, int64."""
        n_hidden = self.lower_.n_hidden
        return (np.asarray(word, np.int64) * n_hidden + previous) * n_hidden + current

    def _count_transitions(self, keys: np.ndarray) -> None:
        """Adds one count per key to the sparse transition table (sorted unique keys, counts)."""
        self.transition_keys_, self.transition_counts_ = _add_sparse_counts(
            self.transition_keys_, self.transition_counts_, keys
        )

    def count_word_statistics(
        self, vision, language, motor, performed=None
    ) -> HierarchicalAssociator:
        """Counts, with the lower level frozen, what the word layer needs to perform: for each
        heard word, lower winner (the recognition winner of vision and motor, as after
        training) and heading sector (``pose_heading_bins``), the number of samples, the sums of
        the pose and of its squares (the vision code's bump centres, in units of the code; the
        heading as a unit vector) and the count of each directive performed there; and, per lower
        winner, the word transitions that lead into its samples (``transition_winner =
        'current'``), and per pair of winners, the step's before and its own (``'pair'``), between
        consecutive samples, across calls too. Call it on the training
        stream once training is over, in order, in pieces if need be (the counts add up);
        ``partial_fit`` drops them, as the lower level then changes. Shapes as for
        :meth:`partial_fit`; ``performed`` (n, 4), the motor codes of what was done at each sample
        when ``motor`` is not that (e.g. directives inferred from the motion into each pose: the
        motion out of it is what was done there), default ``motor``. Returns self."""
        self._check_fitted()
        self.validate_params()
        z = encoding.assemble(vision, language, motor)
        performed = z[:, encoding.MOTOR_SLICE] if performed is None else performed
        performed = encoding.check_codes(performed, N_MOTOR, "performed")
        if performed.shape[0] != z.shape[0]:
            raise ValueError(
                f"performed must have one row per sample ({z.shape[0]}), got {performed.shape[0]}"
            )
        n_words, bins = len(self.vocabulary), int(self.pose_heading_bins)
        n_components = self.lower_.n_hidden * bins
        if not hasattr(self, "word_samples_"):
            self.word_samples_ = np.zeros((n_words, n_components))
            self.word_pose_sums_ = np.zeros((n_words, n_components, 4))
            self.word_pose_squares_ = np.zeros((n_words, n_components, 2))
            self.word_motor_counts_ = np.zeros((n_words, n_components, N_MOTOR))
        if not hasattr(self, "word_transitions_into_"):  # also on files saved before version 0.12.0
            self.word_transitions_into_ = np.zeros((self.lower_.n_hidden, n_words, n_words))
        if not hasattr(self, "pair_transition_keys_"):  # also on files saved before version 0.14.0
            self.pair_transition_keys_ = np.zeros(0, np.int64)
            self.pair_transition_counts_ = np.zeros(0)
        if not hasattr(self, "statistics_last_winner_"):  # loaded files start a new piece
            self.statistics_last_word_, self.statistics_last_winner_ = -1, -1
        if z.shape[0] == 0:
            return self
        self._statistics_changed()
        vision, motor = z[:, encoding.VISION_SLICE], z[:, encoding.MOTOR_SLICE]
        winners = self._lower_winners(vision, motor, 1.0)
        component = winners * bins + heading_sectors(vision, bins)
        words = self._heard_words(z[:, encoding.LANGUAGE_SLICE])
        cell = words * n_components + component
        previous_words = np.concatenate([[self.statistics_last_word_], words[:-1]])
        previous_winners = np.concatenate([[self.statistics_last_winner_], winners[:-1]])
        known = previous_words >= 0
        np.add.at(
            self.word_transitions_into_, (winners[known], previous_words[known], words[known]), 1.0
        )
        self.pair_transition_keys_, self.pair_transition_counts_ = _add_sparse_counts(
            self.pair_transition_keys_,
            self.pair_transition_counts_,
            self._pair_key(
                previous_winners[known], winners[known], previous_words[known], words[known]
            ),
        )
        self.statistics_last_word_, self.statistics_last_winner_ = int(words[-1]), int(winners[-1])
        size = n_words * n_components

        def add(target, weights=None):
            target += np.bincount(cell, weights=weights, minlength=size).reshape(target.shape)

        add(self.word_samples_)
        pose = _pose_features(vision)
        for i in range(4):
            add(self.word_pose_sums_[..., i], pose[:, i])
        for i in range(2):
            add(self.word_pose_squares_[..., i], pose[:, i] ** 2)
        directive = performed.argmax(axis=1)
        for d in range(N_MOTOR):
            add(self.word_motor_counts_[..., d], (directive == d).astype(float))
        return self

    @property
    def has_word_statistics_(self) -> bool:
        """Whether ``count_word_statistics`` has counted since the lower level last learned."""
        return hasattr(self, "word_samples_")

    def _statistics_changed(self) -> None:
        """Forgets what ``_derived`` kept: the word statistics are about to change."""
        self.__dict__.pop("_derived_cache", None)

    def _derived(self, name: str, compute):
        """Returns ``compute()`` (an array or a tuple of arrays, made read-only), computed once
        until the word statistics change (``_statistics_changed``) or a setting it reads does:
        each perform step asks for the same pose components and directive tables."""
        settings = (
            float(self.pose_width_floor),
            int(self.min_word_samples),
            int(self.pose_heading_bins),
        )
        cache = self.__dict__.setdefault("_derived_cache", {})
        kept = cache.get(name)
        if kept is None or kept[0] != settings:
            cache[name] = kept = (settings, compute())
        value = kept[1]
        for array in value if isinstance(value, tuple) else (value,):
            array.flags.writeable = False  # also on a copy's (a deep copy makes them writeable)
        return value

    def _unit_statistics(self):
        """Returns the word statistics per word and lower unit (n_words, n_hidden, ...): samples,
        pose sums, pose squares and directive counts, summed over the heading sectors."""
        return self._derived("unit_statistics", self._count_unit_statistics)

    def _count_unit_statistics(self):
        bins = int(self.pose_heading_bins)
        n_words, n_hidden = len(self.vocabulary), self.lower_.n_hidden
        return tuple(
            values.reshape(n_words, n_hidden, bins, *values.shape[2:]).sum(axis=2)
            for values in (
                self.word_samples_,
                self.word_pose_sums_,
                self.word_pose_squares_,
                self.word_motor_counts_,
            )
        )

    def _pose_components(self, per_unit: bool = True):
        """Returns the word-and-winner pose components (n_words, n_hidden), or with ``per_unit``
        False the word-unit-and-sector ones (n_words, n_hidden x pose_heading_bins): x and y
        means (..., 2) and spreads (..., 2), the heading's mean and spread, all in units of the
        vision code (each spread at least ``pose_width_floor``, the heading's circular), and the
        log of each component's normaliser; components with fewer than ``min_word_samples``
        samples have a normaliser of -inf. Also returns the components' sample counts."""
        return self._derived(
            f"pose_components_{per_unit}", lambda: self._compute_pose_components(per_unit)
        )

    def _compute_pose_components(self, per_unit: bool):
        if per_unit:
            samples, sums, squares, _ = self._unit_statistics()
        else:
            samples, sums, squares = (
                self.word_samples_,
                self.word_pose_sums_,
                self.word_pose_squares_,
            )
        safe = np.maximum(samples, 1.0)
        mean = sums / safe[..., None]
        var = squares / safe[..., None] - mean[..., :2] ** 2
        floor = float(self.pose_width_floor)
        sd_xy = np.sqrt(np.maximum(var, floor**2))
        resultant = np.clip(np.hypot(mean[..., 2], mean[..., 3]), 1e-6, 1.0)
        to_units = N_PHI / (2 * np.pi)
        sd_phi = np.maximum(np.sqrt(-2.0 * np.log(resultant)) * to_units, floor)
        mean_phi = np.arctan2(mean[..., 3], mean[..., 2]) * to_units
        log_norm = -np.log(sd_xy[..., 0] * sd_xy[..., 1] * sd_phi)
        log_norm = np.where(samples >= self.min_word_samples, log_norm, -np.inf)
        # A copy of the counts: the returned arrays are kept read-only (``_derived``).
        return mean[..., :2], sd_xy, mean_phi, sd_phi, log_norm, np.array(samples)

    def _pose_fit_at_winners(self, vision: np.ndarray, winners: np.ndarray) -> np.ndarray:
        """Returns (n, n_words): the Gaussian log-likelihood of each sample's pose under each
        word's component at the sample's winner; components counted fewer than
        ``min_word_samples`` times take the best of the others (no evidence either way)."""
        mean, sd_xy, mean_phi, sd_phi, log_norm, _ = self._pose_components()
        centres = encoding.vision_code_centres(vision)
        half = N_PHI / 2
        k = winners
        dphi = (centres[None, :, 2] - mean_phi[:, k] + half) % N_PHI - half
        squared = (
            ((centres[None, :, 0] - mean[:, k, 0]) / sd_xy[:, k, 0]) ** 2
            + ((centres[None, :, 1] - mean[:, k, 1]) / sd_xy[:, k, 1]) ** 2
            + (dphi / sd_phi[:, k]) ** 2
        )
        fit = (log_norm[:, k] - 0.5 * squared).T
        best = np.max(np.where(np.isfinite(fit), fit, -np.inf), axis=1, keepdims=True)
        best = np.where(np.isfinite(best), best, 0.0)
        return np.where(np.isfinite(fit), fit, best)

    def _pose_log_likelihoods(
        self, vision: np.ndarray, word_index: np.ndarray, per_unit: bool = True
    ) -> np.ndarray:
        """Returns (n, n_components): the log-likelihood of each sample's pose under each
        component of its word (``_pose_components``; per unit, or per unit and heading sector),
        plus the log of its sample count; -inf for components with fewer than
        ``min_word_samples`` samples. The per-sector components are Student-t for
        ``pose_tail_dof`` above 0, the others always Gaussian."""
        mean, sd_xy, mean_phi, sd_phi, log_norm, samples = self._pose_components(per_unit)
        norm = np.log(np.maximum(samples, 1.0)) + log_norm
        centres = encoding.vision_code_centres(vision)
        w = word_index
        half = N_PHI / 2
        dphi = (centres[:, 2, None] - mean_phi[w] + half) % N_PHI - half
        squared = (
            ((centres[:, 0, None] - mean[w, :, 0]) / sd_xy[w, :, 0]) ** 2
            + ((centres[:, 1, None] - mean[w, :, 1]) / sd_xy[w, :, 1]) ** 2
            + (dphi / sd_phi[w]) ** 2
        )
        dof = float(self.pose_tail_dof)
        if per_unit or dof == 0:
            return norm[w] - 0.5 * squared
        return norm[w] - 0.5 * (dof + 3.0) * np.log1p(squared / dof)

    def _heard_words(self, language: np.ndarray) -> np.ndarray:
        codes = encoding.encode_words(list(self.vocabulary))
        distances = ((language[:, None, :] - codes[None]) ** 2).sum(axis=2)
        return distances.argmin(axis=1)

    # ------------------------------------------------------------------------------------------
    # Read-outs

    def word_likelihoods_(self) -> np.ndarray:
        """Returns ``p(lower winner | word)``, shape (n_words, n_hidden)."""
        self._check_fitted()
        links = self.word_links_ + self.link_floor
        return links / links.sum(axis=1, keepdims=True)

    def word_transition_probabilities_(self) -> np.ndarray:
        """Returns ``p(word_t | word_(t-1))``, shape (n_words, n_words), rows summing to one."""
        self._check_fitted()
        counts = self.word_transitions_ + self.word_transition_floor
        return counts / counts.sum(axis=1, keepdims=True)

    def _pair_key(self, previous, current, previous_word, word) -> np.ndarray:
        """Returns the index of (previous winner, current winner, previous word, word) in a
        flattened (n_hidden, n_hidden, n_words, n_words) table, int64: the pair table's key."""
        n_hidden, n_words = self.lower_.n_hidden, len(self.vocabulary)
        previous = np.asarray(previous, np.int64)
        return ((previous * n_hidden + current) * n_words + previous_word) * n_words + word

    def _word_transitions_at(self, previous: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Returns the word transitions into each of ``n`` steps, shape (n, n_words, n_words):
        ``p(word_t | word_(t-1), k_t)`` at the current winners ``current`` (n,) with
        ``transition_winner`` 'current' or 'pair' and its counts, else ``p(word_t | word_(t-1),
        k_(t-1))`` at the previous winners ``previous`` (n,); backed off to ``p(word_t |
        word_(t-1))``, which is taken alone where that winner is -1 (not seen) or for a network
        without the counts (files written before them). With 'pair' and its counts, where both
        winners are known, ``p(word_t | word_(t-1), k_(t-1), k_t)`` backed off in turn to those
        with ``pair_transition_prior``."""
        out = self._single_winner_transitions(previous, current)
        if self.transition_winner != "pair" or not hasattr(self, "pair_transition_keys_"):
            return out
        previous, current = np.asarray(previous), np.asarray(current)
        known = (previous >= 0) & (current >= 0)
        n_words = len(self.vocabulary)
        if not np.any(known):
            return out
        first = self._pair_key(previous[known], current[known], 0, 0)
        wanted = first[:, None] + np.arange(n_words * n_words)  # (word_(t-1), word_t) blocks
        counts = _sparse_counts_at(
            self.pair_transition_keys_, self.pair_transition_counts_, wanted
        ).reshape(-1, n_words, n_words)
        prior = float(self.pair_transition_prior)
        out[known] = (counts + prior * out[known]) / (counts.sum(axis=2, keepdims=True) + prior)
        return out

    def _single_winner_transitions(self, previous: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Returns :meth:`_word_transitions_at`'s transitions at one winner: the current one
        ('current' or 'pair', with its counts) or the previous one."""
        overall = self.word_transition_probabilities_()
        out = np.broadcast_to(overall, (len(previous), *overall.shape)).copy()
        if self.transition_winner in ("current", "pair") and hasattr(
            self, "word_transitions_into_"
        ):
            table, winners = self.word_transitions_into_, np.asarray(current)
        else:
            table, winners = getattr(self, "word_unit_transitions_", None), np.asarray(previous)
        known = winners >= 0
        if table is not None and np.any(known):
            counts = table[winners[known]]
            prior = float(self.unit_transition_prior)
            out[known] = (counts + prior * overall) / (counts.sum(axis=2, keepdims=True) + prior)
        return out

    def _lower_winners(self, vision, motor, motor_weight: float) -> np.ndarray:
        """Returns the lower winners of vision (n, 96) and motor (n, 4) codes, language silent,
        the motor area weighted by ``motor_gain`` x ``motor_weight``."""
        self._check_fitted()
        check_motor_weight(motor_weight)
        vision = encoding.check_codes(vision, N_VISION, "vision")
        motor = encoding.check_codes(motor, N_MOTOR, "motor")
        if vision.shape[0] != motor.shape[0]:
            raise ValueError(
                f"vision and motor must have the same number of samples, got "
                f"{vision.shape[0]} and {motor.shape[0]}"
            )
        return self.lower_.winners(vision, motor=motor * (self.motor_gain * motor_weight))

    def _sequence_evidence(self, previous: np.ndarray, current: np.ndarray) -> np.ndarray:
        """Returns ``p(k_t | k_(t-1), word)`` for winners ``current`` (n,) after ``previous`` (n,),
        shape (n, n_words); where ``previous`` is -1 (not seen), ``p(k_t | word)``."""
        n_hidden = self.lower_.n_hidden
        n_words = len(self.vocabulary)
        single = self.word_likelihoods_()[:, current].T
        evidence = single.copy()
        known = previous >= 0
        table = self.transition_keys_
        if not np.any(known) or len(table) == 0:  # no transition counted: p(k_t | word)
            return evidence
        before, now = previous[known], current[known]
        keys = self._transition_key(np.arange(n_words)[None, :], before[:, None], now[:, None])
        counts = _sparse_counts_at(table, self.transition_counts_, keys)
        leaving = (
            np.bincount(
                table // n_hidden, weights=self.transition_counts_, minlength=n_words * n_hidden
            )
            .reshape(n_words, n_hidden)[:, before]
            .T
        )
        prior = self.transition_prior
        evidence[known] = (counts + prior * single[known]) / (leaving + prior)
        return evidence

    def recognise_sequence(
        self,
        vision,
        motor,
        motor_weight: float = 1.0,
        seen=None,
        state: SequenceState | None = None,
    ) -> SequenceRecognition:
        """Recognises ``n`` consecutive samples over time: a belief over the words carried from
        step to step, a causal forward filter through the word transitions at the winner
        ``transition_winner`` names, ``p(word_t | word_(t-1), k_t)`` or ``p(word_t | word_(t-1),
        k_(t-1))`` (backed off to ``p(word_t | word_(t-1))``), and the evidence ``p(k_t |
        k_(t-1), word)`` of the lower winners (backed off to ``p(k_t | word)``), times
        ``N(pose_t | word, k_t) ** pose_evidence`` once the word statistics are counted.

        Args:
          vision, motor: (m, 96) and (m, 4) codes of the samples that were seen, in order.
          motor_weight: as for :meth:`recognise_batch`.
          seen: (n,) bool, which of the ``n`` consecutive steps were seen (``m`` of them); on a
            step not seen the belief only follows the word transitions. Default: all seen.
          state: where a previous call ended (its ``state``), to continue a stream in pieces;
            default: a uniform belief and no previous winner.
        """
        winners_seen = self._lower_winners(vision, motor, motor_weight)
        m = len(winners_seen)
        seen = np.ones(m, bool) if seen is None else np.asarray(seen)
        if seen.ndim != 1 or seen.dtype != bool or int(seen.sum()) != m:
            raise ValueError(
                f"seen must be a 1-D bool array with one True per vision sample ({m}), got "
                f"dtype {seen.dtype}, shape {seen.shape}, {int(np.count_nonzero(seen))} True"
            )
        n_words = len(self.vocabulary)
        state = self._check_state(state)
        winners = np.full(len(seen), -1, np.int64)
        winners[seen] = winners_seen
        previous = np.concatenate([[state.last_winner], winners[:-1]])
        evidence = np.ones((len(seen), n_words))
        evidence[seen] = self._sequence_evidence(previous[seen], winners_seen)
        if self.has_word_statistics_ and m:  # how well each word's component fits the pose
            fit = self._pose_fit_at_winners(np.asarray(vision, float), winners_seen)
            evidence[seen] *= np.exp(self.pose_evidence * (fit - fit.max(axis=1, keepdims=True)))
        # Where the words changed: the transitions at the winner ``transition_winner`` names (not
        # seen: the overall ones).
        transitions = self._word_transitions_at(previous, winners)
        beliefs = np.empty((len(seen), n_words))
        belief = state.posterior
        # The forward filter, one step at a time. Every transition probability and every
        # evidence value is positive (the floors and the prior are validated positive), so the
        # product never sums to zero.
        for t, e in enumerate(evidence):
            belief = (belief @ transitions[t]) * e
            belief /= belief.sum()
            beliefs[t] = belief
        last = int(winners[-1]) if len(seen) else state.last_winner
        with np.errstate(divide="ignore"):
            scores = np.log(beliefs)
        words = np.asarray(self.vocabulary)[np.argmax(beliefs, axis=1)]
        return SequenceRecognition(words, scores, winners, SequenceState(belief.copy(), last))

    def _check_state(self, state) -> SequenceState:
        n_words = len(self.vocabulary)
        if state is None:
            return SequenceState(np.full(n_words, 1.0 / n_words), -1)
        posterior = np.asarray(state.posterior, dtype=float)
        last = state.last_winner
        if (
            posterior.shape != (n_words,)
            or not np.all(np.isfinite(posterior))
            or np.any(posterior < 0)
            or not np.isclose(posterior.sum(), 1.0)
        ):
            raise ValueError(
                f"state.posterior must be {n_words} non-negative numbers summing to one, got "
                f"{posterior!r}"
            )
        if not (isinstance(last, (int, np.integer)) and -1 <= last < self.lower_.n_hidden):
            raise ValueError(
                f"state.last_winner must be -1 or a hidden unit index below "
                f"{self.lower_.n_hidden}, got {last!r}"
            )
        return SequenceState(posterior, int(last))

    def recognise_batch(self, vision, motor, motor_weight: float = 1.0) -> BatchRecognition:
        """Recognises ``n`` samples from vision (n, 96) and motor (n, 4) codes; ``scores`` are
        ``log p(winner | word)`` per vocabulary word, ``winners`` the lower winners.

        ``motor_weight`` is the read-out's weight on the motor area in the bottom-up pass, on top
        of the hyper-parameter ``motor_gain`` (1: the read-out the lower level learned with)."""
        winners = self._lower_winners(vision, motor, motor_weight)
        scores = np.log(self.word_likelihoods_()).T[winners]
        words = np.asarray(self.vocabulary)[np.argmax(scores, axis=1)]
        return BatchRecognition(words, scores, winners)

    def recognise(self, vision, motor, motor_weight: float = 1.0) -> Recognition:
        """Recognises one sample; see :meth:`recognise_batch` (``hidden`` is the lower r^c)."""
        batch = self.recognise_batch(np.atleast_2d(vision), np.atleast_2d(motor), motor_weight)
        return Recognition(
            str(batch.words[0]), batch.scores[0], self.lower_.hidden_code(batch.winners[0])
        )

    def _word_index(self, words, n: int) -> np.ndarray:
        """Returns (n,) vocabulary indices of one word for all ``n`` samples or of a sequence
        of ``n`` words (ValueError naming any other word, or a sequence of another length)."""
        names = [words] * n if isinstance(words, str) else _word_list(words, self.vocabulary)
        if len(names) != n:
            raise ValueError(
                f"vision and words must have the same number of samples, got {n} and {len(names)}"
            )
        return word_indices(names, self.vocabulary)

    def perform_batch(self, vision, words) -> BatchPerformance:
        """Chooses motor directives for ``n`` samples from vision (n, 96) and words (one word for
        all, or a sequence of ``n`` vocabulary words; ValueError naming any other).

        With ``perform_readout = "posterior"`` and counted components, the output is the
        mixture of the counted components weighted by their posterior
        ``softmax(log n_k + log N(pose | word, k))`` (``_mix_directives``; the winner reported is
        the most probable component); otherwise, as follows.

        The winner maximises ``cos(v, W_bu,k[vision]) + word_bias * log p(k | word)``, plus
        ``pose_weight * log N(pose | word, k)`` once ``count_word_statistics`` has counted; the
        output is then ``p(directive | k, word)`` (with ``perform_temperature`` > 0, its mixture
        over the counted components, ``_mixture_motor``), else the lower level's motor area
        reconstructed at the winner (divided by ``motor_gain``)."""
        self._check_fitted()
        vision = encoding.check_codes(vision, N_VISION, "vision")
        n = vision.shape[0]
        word_index = self._word_index(words, n)
        lower = self.lower_
        # Cosine between the vision code and each unit's vision weights: each unit's bottom-up
        # weights were normalised with the motor area present, so their vision parts differ in
        # length and a plain product would favour a few units whose weights lie mostly on vision,
        # whatever the pose.
        w_vision = lower.W_bu_[:, encoding.VISION_SLICE].astype(float)
        w_vision /= np.maximum(np.linalg.norm(w_vision, axis=1, keepdims=True), 1e-12)
        log_links = self.word_bias * np.log(self.word_likelihoods_())
        motor_td = lower.readout_tables().motor / self.motor_gain
        winners = np.empty(n, np.int64)
        motor = np.empty((n, N_MOTOR))
        # Bounded memory: (chunk, n_hidden x pose_heading_bins) at a time.
        chunk = max(1, _PERFORM_CHUNK // int(self.pose_heading_bins))
        for start in range(0, n, chunk):
            part = slice(start, min(start + chunk, n))
            v, w = vision[part], word_index[part]
            lengths = np.maximum(np.linalg.norm(v, axis=1, keepdims=True), 1e-12)
            activation = (v / lengths) @ w_vision.T + log_links[w]
            # Before counting, and for words without counted components: the lower W_td.
            winners[part] = activation.argmax(axis=1)
            motor[part] = motor_td[winners[part]]
            if not self.has_word_statistics_:
                continue
            if self.perform_readout == "posterior":
                sectors = self._pose_log_likelihoods(v, w, per_unit=False)
                rows = np.flatnonzero(np.isfinite(sectors).any(axis=1))  # components to mix
                posterior, motor[start + rows] = self._mix_directives(
                    sectors[rows], w[rows], self._directive_table(per_unit=False)
                )
                # The most probable component's unit.
                winners[start + rows] = posterior.argmax(axis=1) // int(self.pose_heading_bins)
                continue
            pose = self._pose_log_likelihoods(v, w)
            counted = np.isfinite(pose).any(axis=1)  # the word has components to choose from
            activation[counted] += self.pose_weight * pose[counted]
            k = activation.argmax(axis=1)
            winners[part] = k
            counts = self._unit_statistics()[3][w, k]
            totals = counts.sum(axis=1, keepdims=True)
            motor[part] = np.where(counted[:, None], counts / np.maximum(totals, 1.0), motor_td[k])
            if self.perform_temperature > 0 and np.any(counted):
                rows = np.flatnonzero(counted)
                motor[start + rows] = self._mixture_motor(activation[rows], w[rows])
        best = motor.argmax(axis=1)
        return BatchPerformance(np.asarray(DIRECTIVES)[best], motor, winners)

    def _mixture_motor(self, activation: np.ndarray, word_index: np.ndarray) -> np.ndarray:
        """Returns (n, 4): ``sum_k softmax(activation / perform_temperature)_k p(d | k, word)``
        over the word's counted components (the others, at -inf, weigh nothing)."""
        table = self._directive_table(per_unit=True)
        return self._mix_directives(activation / self.perform_temperature, word_index, table)[1]

    def _directive_table(self, per_unit: bool) -> np.ndarray:
        """Returns ``p(d | k, word)`` (n_words, n_components, 4) from the directive counts of
        each word's components: per lower unit, or per unit and heading sector (0 where none)."""

        def compute():
            counts = self._unit_statistics()[3] if per_unit else self.word_motor_counts_
            return counts / np.maximum(counts.sum(axis=2, keepdims=True), 1.0)

        return self._derived(f"directive_table_{per_unit}", compute)

    def _mix_directives(self, log_weights: np.ndarray, word_index: np.ndarray, table):
        """Returns ``softmax(log_weights)`` (n, n_components; -inf weighs nothing) and the mixture
        (n, 4) of the components' directive distributions ``p(d | k, word)`` it weights, from
        their ``table`` (n_words, n_components, 4; ``_directive_table``)."""
        weights = np.exp(log_weights - log_weights.max(axis=1, keepdims=True))
        weights /= weights.sum(axis=1, keepdims=True)
        out = np.empty((len(log_weights), N_MOTOR))
        for word in np.unique(word_index):
            rows = word_index == word
            out[rows] = weights[rows] @ table[word]
        return weights, out

    def pose_log_density(self, vision, words) -> np.ndarray:
        """Returns (n,): the log of the word's demonstration density at each vision code's pose,
        ``log sum_k n_k p(pose | word, k)`` over the posterior read-out's counted components
        (per unit and heading sector; -inf where the word has none), for vision (n, 96) and one
        word or a sequence of ``n`` vocabulary words. Needs ``count_word_statistics``."""
        self._check_fitted()
        if not self.has_word_statistics_:
            raise ValueError("pose_log_density needs count_word_statistics first")
        vision = encoding.check_codes(vision, N_VISION, "vision")
        n = vision.shape[0]
        word_index = self._word_index(words, n)
        out = np.empty(n)
        chunk = max(1, _PERFORM_CHUNK // int(self.pose_heading_bins))
        for start in range(0, n, chunk):
            part = slice(start, min(start + chunk, n))
            log = self._pose_log_likelihoods(vision[part], word_index[part], per_unit=False)
            top = np.max(log, axis=1)
            safe = np.where(np.isfinite(top), top, 0.0)
            with np.errstate(divide="ignore"):
                total = np.log(np.exp(log - safe[:, None]).sum(axis=1))
            out[part] = np.where(np.isfinite(top), safe + total, -np.inf)
        return out

    def perform(self, vision, word) -> Performance:
        """Chooses the motor directive for one vision code (96,) and word; see
        :meth:`perform_batch`."""
        if not isinstance(word, str):
            raise ValueError(f"word must be a vocabulary word, got {type(word).__name__}")
        batch = self.perform_batch(np.atleast_2d(vision), word)
        return Performance(
            str(batch.directives[0]), batch.motor[0], self.lower_.hidden_code(batch.winners[0])
        )


def _add_sparse_counts(keys: np.ndarray, counts: np.ndarray, new: np.ndarray):
    """Returns a sparse count table (sorted unique int64 keys, their counts) with one more count
    per key in ``new``."""
    if len(new) == 0:
        return keys, counts
    new_keys, new_counts = np.unique(np.asarray(new, np.int64), return_counts=True)
    merged, inverse = np.unique(np.concatenate([keys, new_keys]), return_inverse=True)
    counts = np.bincount(
        inverse, weights=np.concatenate([counts, new_counts]), minlength=len(merged)
    )
    return merged, counts


def _sparse_counts_at(keys: np.ndarray, counts: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Returns the counts of a sparse count table (sorted unique keys, their counts) at the keys
    ``wanted`` (any shape), 0 where a key is not in the table."""
    if len(keys) == 0:
        return np.zeros(np.shape(wanted))
    at = np.minimum(np.searchsorted(keys, wanted), len(keys) - 1)
    return np.where(keys[at] == wanted, counts[at], 0.0)
