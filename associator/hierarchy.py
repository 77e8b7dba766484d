"""A two-level associator: the paper's network on vision and motor, and a word layer above it.

Why: in the paper's flat network (``associator.network``) each hidden unit learns vision, motor
and language together, so the map divides itself into word regions that each hold a copy of the
arena. Recognition omits language, and the winner is then chosen by vision and motor alone among
all regions: near walls, where 'go' and 'pick' look alike, it often falls in the wrong word's
region. The authors' follow-up MirrorBot models (Wermter, Weber, Elshaw et al., "A mirror neuron
inspired hierarchical network for action selection", 2005) put a lower area on vision and motor
and associate its hidden code with language in a higher area. This module is the smallest such
hierarchy:

- Lower level: the paper's network and learning rule unchanged (:class:`~associator.network.
  Associator`), trained with the language area silent, so the whole map quantises vision and
  motor, and recognition's winner is found exactly as it was learned. The motor area is
  multiplied by ``motor_gain`` (training and read-outs alike): one active motor unit against
  about twenty active vision units barely moves the winner otherwise.
- Word layer: one unit per vocabulary word, linked to the lower winners by Hebbian counting:
  each wake step adds one to the link between the heard word and the lower winner. Each word
  unit's links are normalised to sum to one, so a word's activation for a lower winner ``k`` is
  the learned ``p(k | word)``. (Weighting the links by the paper's wake rate, with its fivefold
  boost on motor changes, lowered 'pick' recognition by 1.4 points in our measurement.)

Read-outs:

- Recognition (vision and motor given): the lower winner ``k``; the word with the largest
  ``p(k | word)`` (a likelihood read-out: a frequent word does not win by frequency alone).
- Performance (vision and word given, motor omitted): the word biases the lower level's
  competition top-down: the winner maximises ``(W_bu z)_k + word_bias * log p(k | word)`` with
  only the vision area of ``z`` active, so among units that match what the student sees, those
  the word was heard at win. The motor area reconstructed through the lower ``W_td`` at that
  winner (divided by ``motor_gain``) is the graded output, its strongest unit the directive.
"""

from __future__ import annotations

import numpy as np

from associator import encoding
from associator.encoding import DIRECTIVES, N_MOTOR, N_VISION
from associator.network import (
    Associator,
    BatchPerformance,
    BatchRecognition,
    Performance,
    Recognition,
    check_motor_changed,
)

#: Hyper-parameters of the word layer and the motor gain; everything else is the lower network's.
_OWN_PARAMS = ("motor_gain", "link_floor", "word_bias")


class HierarchicalAssociator:
    """The two-level associator, in the scikit-learn shape of :class:`Associator`.

    Parameters
    ----------
    motor_gain : float
        Factor on the motor area at the lower level, in training and read-outs. Default 3: on the
        seed-0 streams recognition went from 87.2 / 92.8 / 99.8 % (go / pick / lift, gain 1) to
        89.3 / 92.3 / 100 % (``docs/associator.md``).
    link_floor : float
        Added to every word-to-winner link (a count) before normalising, so that a winner never
        seen with a word is unlikely for it, not impossible.
    word_bias : float
        Weight of ``log p(k | word)`` against the bottom-up activation in performance (0.1:
        chosen on the synthetic teacher of the tests, where motor recall was 0.71 balanced with
        0, and 0.78 / 0.69 for 'go' / 'pick' against 0.62 / 0.24 unbiased).
    **lower_params
        Hyper-parameters of the lower network (:class:`Associator`; ``vocabulary`` and ``rng``
        included), the paper's defaults otherwise.
    """

    def __init__(
        self,
        *,
        motor_gain: float = 3.0,
        link_floor: float = 1e-3,
        word_bias: float = 0.1,
        **lower_params,
    ):
        self.motor_gain = motor_gain
        self.link_floor = link_floor
        self.word_bias = word_bias
        self.lower_params = dict(lower_params)

    def get_params(self) -> dict:
        """Returns the hyper-parameters (the lower network's included, ``rng`` excluded)."""
        params = Associator(**self.lower_params).get_params()
        params.update(
            motor_gain=float(self.motor_gain),
            link_floor=float(self.link_floor),
            word_bias=float(self.word_bias),
        )
        return params

    @property
    def vocabulary(self) -> tuple[str, ...]:
        return tuple(self.lower_params.get("vocabulary", encoding.WORDS))

    def _validate_params(self) -> None:
        for name in _OWN_PARAMS:
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")

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
        for name in ("lower_", "word_links_"):
            self.__dict__.pop(name, None)
        return self.partial_fit(vision, language, motor, motor_changed)

    def partial_fit(self, vision, language, motor, motor_changed=None) -> HierarchicalAssociator:
        """Trains both levels on ``n`` consecutive samples (shapes as for
        :meth:`Associator.partial_fit`); the heard word of each sample is its language code's
        nearest vocabulary word."""
        self._validate_params()
        z = encoding.assemble(vision, language, motor)
        n = z.shape[0]
        changed = check_motor_changed(motor_changed, n)
        if not hasattr(self, "lower_"):
            self.lower_ = Associator(**self.lower_params)
            self.word_links_ = np.zeros((len(self.vocabulary), self.lower_.n_hidden))
        words = self._heard_words(z[:, encoding.LANGUAGE_SLICE])
        z[:, encoding.LANGUAGE_SLICE] = 0.0  # the lower level never hears language
        z[:, encoding.MOTOR_SLICE] *= self.motor_gain
        winners = np.empty(n, np.int64)  # each sample's wake winner, for the word links
        self.lower_._learn(z, changed, winners)
        np.add.at(self.word_links_, (words, winners), 1.0)
        return self

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

    def recognise_batch(self, vision, motor, motor_gain: float = 1.0) -> BatchRecognition:
        """Recognises ``n`` samples from vision (n, 96) and motor (n, 4) codes; ``scores`` are
        ``log p(winner | word)`` per vocabulary word, ``winners`` the lower winners.

        ``motor_gain`` weights the motor area further in the read-out, on top of ``motor_gain`` of
        the hyper-parameters (1: none), as :meth:`Associator.recognise_batch` does."""
        self._check_fitted()
        if not (np.isfinite(motor_gain) and motor_gain > 0):
            raise ValueError(f"motor_gain must be a positive number, got {motor_gain!r}")
        vision = encoding.check_codes(vision, N_VISION, "vision")
        motor = encoding.check_codes(motor, N_MOTOR, "motor")
        if vision.shape[0] != motor.shape[0]:
            raise ValueError(
                f"vision and motor must have the same number of samples, got "
                f"{vision.shape[0]} and {motor.shape[0]}"
            )
        winners = self.lower_._winners(vision, None, motor * (self.motor_gain * motor_gain))
        scores = np.log(self.word_likelihoods_()).T[winners]
        words = np.asarray(self.vocabulary)[np.argmax(scores, axis=1)]
        return BatchRecognition(words, scores, winners)

    def recognise(self, vision, motor, motor_gain: float = 1.0) -> Recognition:
        """Recognises one sample; see :meth:`recognise_batch` (``hidden`` is the lower r^c)."""
        batch = self.recognise_batch(np.atleast_2d(vision), np.atleast_2d(motor), motor_gain)
        return Recognition(
            str(batch.words[0]), batch.scores[0], self.lower_.hidden_code(batch.winners[0])
        )

    def perform_batch(self, vision, words) -> BatchPerformance:
        """Chooses motor directives for ``n`` samples from vision (n, 96) and words (one word for
        all, or a sequence of ``n`` vocabulary words); see the module notes."""
        self._check_fitted()
        vision = encoding.check_codes(vision, N_VISION, "vision")
        n = vision.shape[0]
        names = [words] * n if isinstance(words, str) else list(words)
        if len(names) != n:
            raise ValueError(
                f"vision and words must have the same number of samples, got {n} and {len(names)}"
            )
        unknown = sorted({w for w in names if w not in self.vocabulary})
        if unknown:
            raise ValueError(f"unknown words {unknown}; the network knows: {self.vocabulary}")
        word_index = np.array([self.vocabulary.index(w) for w in names])
        lower = self.lower_
        activation = vision.astype(lower.W_bu_.dtype) @ lower.W_bu_[:, encoding.VISION_SLICE].T
        activation += self.word_bias * np.log(self.word_likelihoods_())[word_index]
        winners = activation.argmax(axis=1)
        motor = lower._readout_tables()[1][winners] / self.motor_gain
        best = motor.argmax(axis=1)
        return BatchPerformance(np.asarray(DIRECTIVES)[best], motor, winners)

    def perform(self, vision, word) -> Performance:
        """Chooses the motor directive for one vision code (96,) and word; see
        :meth:`perform_batch`."""
        if not isinstance(word, str):
            raise ValueError(f"word must be a vocabulary word, got {type(word).__name__}")
        batch = self.perform_batch(np.atleast_2d(vision), word)
        return Performance(
            str(batch.directives[0]), batch.motor[0], self.lower_.hidden_code(batch.winners[0])
        )
