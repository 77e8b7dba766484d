"""The associator network of Elshaw et al. (section III): a Helmholtz machine with a competitive,
smoothed-localist hidden code, trained by a modified wake-sleep algorithm.

Shapes: ``z`` has 180 input units (see ``associator.encoding``), the hidden layer is a 16 x 48 grid
of 768 units numbered row-major, ``W_bu_`` is (768, 180) and ``W_td_`` is (180, 768).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from associator import _fast, encoding
from associator.encoding import (
    DIRECTIVES,
    LANGUAGE_SLICE,
    MOTOR_SLICE,
    N_INPUT,
    N_LANGUAGE,
    N_MOTOR,
    N_VISION,
    VISION_SLICE,
    WORDS,
)

SLEEP_SIGNS = ("self_organising", "printed")
DTYPES = ("float32", "float64")


class Recognition(NamedTuple):
    """What the network recognises from vision and motor input.

    Attributes:
      word: the vocabulary word with the highest score.
      scores: cosine similarity of the reconstructed language area with each vocabulary word's
        code, shape (n_words,), in ``vocabulary`` order.
      hidden: the competitive hidden code r^c, shape (768,) (row-major 16 x 48 grid).
    """

    word: str
    scores: np.ndarray
    hidden: np.ndarray


class Performance(NamedTuple):
    """What the network does given vision and a word.

    Attributes:
      directive: the motor directive with the strongest reconstructed activation.
      motor: the reconstructed motor area, shape (4,) in ``DIRECTIVES`` order, >= 0 (graded).
      hidden: the competitive hidden code r^c, shape (768,).
    """

    directive: str
    motor: np.ndarray
    hidden: np.ndarray


class BatchRecognition(NamedTuple):
    """Recognition of ``n`` samples: ``words`` (n,) str, ``scores`` (n, n_words), ``winners`` (n,)
    hidden winner indices (``Associator.hidden_code`` turns them into r^c)."""

    words: np.ndarray
    scores: np.ndarray
    winners: np.ndarray


class BatchPerformance(NamedTuple):
    """Performance of ``n`` samples: ``directives`` (n,) str, ``motor`` (n, 4), ``winners`` (n,)."""

    directives: np.ndarray
    motor: np.ndarray
    winners: np.ndarray


class ReadoutTables(NamedTuple):
    """What the network reads out when hidden unit k wins (units numbered row-major), read-only.

    Attributes:
      language: the language area reconstructed through W_td from unit k's competitive code r^c,
        shape (n_hidden, 80).
      motor: the motor area reconstructed likewise, shape (n_hidden, 4).
      scores: cosine similarity of each ``language`` row with each vocabulary word's code, shape
        (n_hidden, n_words), in ``vocabulary`` order.
    """

    language: np.ndarray
    motor: np.ndarray
    scores: np.ndarray


#: Samples whose winners ``Associator.winners`` finds at a time (its work array is chunk x n_hidden).
_WINNER_CHUNK = 32768


class Associator:
    """The associator network, in the scikit-learn shape.

    Parameters
    ----------
    hidden_shape : (int, int)
        Rows and columns of the hidden grid (paper: 16 x 48).
    eta : float
        Wake (top-down) learning rate (paper: 0.001).
    epsilon : float
        Sleep (bottom-up) learning rate (paper: 0.01).
    motor_change_boost : float
        Factor on ``eta`` for samples whose active motor unit changed (paper: 5).
    envelope_sigma : float
        Standard deviation in grid units of the Gaussian envelope of the competitive code, in wake
        and sleep alike (not given in the paper; default 1.0).
    envelope_cutoff : float
        The envelope is zero beyond ``ceil(envelope_cutoff * envelope_sigma)`` units along either
        grid axis (a square window; 3 -> 7 x 7 units for sigma 1). The largest value dropped is
        ``exp(-(h + 1)**2 / (2 sigma**2))`` with h that half-width: 3.4e-4 for the defaults.
    decay_fraction : float
        Both rates fall linearly to zero over this last fraction of ``n_steps_total`` (paper: 1/4).
    n_steps_total : int
        Planned number of training samples; the rate schedule depends on the step count against it,
        so chunked training equals one call. After it, rates are zero.
    sleep_sign : {"self_organising", "printed"}
        ``"self_organising"``: dW_bu = epsilon (z^s - w) r~^c, moving weights towards the dream
        (default; ``docs/associator.md`` gives the evidence); ``"printed"``: the paper's printed
        epsilon (w - z^s) r~^c.
    sleeps_per_wake : int
        Sleep phases after each wake phase (the paper alternates; default 1).
    init_scale : float
        W_td starts uniform in [0, init_scale); W_bu starts uniform in [0, 1) with unit-length rows.
        Small top-down weights let the first wake phases, not the initial noise, shape the map.
    vocabulary : tuple of str
        The words the network knows: recognition compares with their codes, performance accepts
        only them (default ``WORDS``).
    dtype : {"float32", "float64"}
        Precision of the weights: float32 (default, faster) or float64 (for checks).
    rng : None, int or numpy.random.Generator
        Source of the initial weights and of the sleep phases' random hidden positions.
    """

    def __init__(
        self,
        *,
        hidden_shape: tuple[int, int] = (16, 48),
        eta: float = 0.001,
        epsilon: float = 0.01,
        motor_change_boost: float = 5.0,
        envelope_sigma: float = 1.0,
        envelope_cutoff: float = 3.0,
        decay_fraction: float = 0.25,
        n_steps_total: int = 1_000_000,
        sleep_sign: str = "self_organising",
        sleeps_per_wake: int = 1,
        init_scale: float = 0.01,
        vocabulary: tuple[str, ...] = WORDS,
        dtype: str = "float32",
        rng=None,
    ):
        self.hidden_shape = hidden_shape
        self.eta = eta
        self.epsilon = epsilon
        self.motor_change_boost = motor_change_boost
        self.envelope_sigma = envelope_sigma
        self.envelope_cutoff = envelope_cutoff
        self.decay_fraction = decay_fraction
        self.n_steps_total = n_steps_total
        self.sleep_sign = sleep_sign
        self.sleeps_per_wake = sleeps_per_wake
        self.init_scale = init_scale
        self.vocabulary = vocabulary
        self.dtype = dtype
        self.rng = rng

    # ------------------------------------------------------------------------------------------
    # Hyper-parameters

    def get_params(self) -> dict:
        """Returns the hyper-parameters as a dict (``rng`` excluded: its state is learned state)."""
        return {
            "hidden_shape": tuple(int(v) for v in self.hidden_shape),
            "eta": float(self.eta),
            "epsilon": float(self.epsilon),
            "motor_change_boost": float(self.motor_change_boost),
            "envelope_sigma": float(self.envelope_sigma),
            "envelope_cutoff": float(self.envelope_cutoff),
            "decay_fraction": float(self.decay_fraction),
            "n_steps_total": int(self.n_steps_total),
            "sleep_sign": str(self.sleep_sign),
            "sleeps_per_wake": int(self.sleeps_per_wake),
            "init_scale": float(self.init_scale),
            "vocabulary": tuple(self.vocabulary),
            "dtype": str(self.dtype),
        }

    def validate_params(self) -> None:
        """Raises ValueError naming the first bad hyper-parameter and what is allowed."""
        shape = self.hidden_shape
        if (
            not isinstance(shape, (tuple, list))
            or len(shape) != 2
            or not all(isinstance(v, (int, np.integer)) and v > 0 for v in shape)
        ):
            raise ValueError(f"hidden_shape must be two positive ints, got {shape!r}")
        for name in ("eta", "epsilon", "init_scale", "envelope_sigma", "envelope_cutoff"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and np.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive finite number, got {value!r}")
        boost = self.motor_change_boost
        if not (isinstance(boost, (int, float)) and np.isfinite(boost) and boost >= 1):
            raise ValueError(f"motor_change_boost must be a finite number >= 1, got {boost!r}")
        fraction = self.decay_fraction
        if not (isinstance(fraction, (int, float)) and 0 <= fraction <= 1):
            raise ValueError(f"decay_fraction must be in [0, 1], got {fraction!r}")
        for name in ("n_steps_total", "sleeps_per_wake"):
            value = getattr(self, name)
            if not (isinstance(value, (int, np.integer)) and value >= 1):
                raise ValueError(f"{name} must be an int >= 1, got {value!r}")
        if self.sleep_sign not in SLEEP_SIGNS:
            raise ValueError(f"unknown sleep_sign {self.sleep_sign!r}; allowed: {SLEEP_SIGNS}")
        if self.dtype not in DTYPES:
            raise ValueError(f"unknown dtype {self.dtype!r}; allowed: {DTYPES}")
        vocabulary = self.vocabulary
        if isinstance(vocabulary, str) or len(vocabulary) < 1:
            raise ValueError(
                f"vocabulary must be a non-empty sequence of words, got {vocabulary!r}"
            )
        if len(set(vocabulary)) != len(vocabulary):
            raise ValueError(f"vocabulary has repeated words: {vocabulary!r}")

    # ------------------------------------------------------------------------------------------
    # Learned state

    @property
    def W_bu_(self) -> np.ndarray:  # noqa: N802 (the paper's name)
        """Bottom-up weights, shape (768, 180): row j is hidden unit j's input weights (a copy;
        hidden units are numbered row-major on the grid)."""
        return self._w_bu[self._layout.storage_of_grid]

    @property
    def W_td_(self) -> np.ndarray:  # noqa: N802
        """Top-down weights, shape (180, 768) (a copy, hidden units numbered row-major)."""
        return self._w_td_t[self._layout.storage_of_grid].T

    @property
    def n_hidden(self) -> int:
        """Returns the number of hidden units (768 for the paper's grid)."""
        return int(self.hidden_shape[0]) * int(self.hidden_shape[1])

    def _check_fitted(self) -> None:
        if not hasattr(self, "_w_bu"):
            raise ValueError("this Associator is not fitted yet; call fit or partial_fit first")

    @classmethod
    def from_state(cls, params: dict, W_bu, W_td, n_steps: int, generator) -> Associator:
        """Returns a fitted network from its learned state (the loading hook of
        ``associator.persistence``).

        Parameters
        ----------
        params : dict
            Hyper-parameters as ``get_params`` returns them (``rng`` excluded).
        W_bu : array, shape (n_hidden, 180)
            Bottom-up weights in the dtype of ``params``, finite and >= 0, hidden units row-major.
        W_td : array, shape (180, n_hidden)
            Top-down weights, likewise.
        n_steps : int
            Training samples seen, >= 0 (the rate schedule continues from it).
        generator : numpy.random.Generator
            The generator, in the state training continues from.

        Raises ValueError for hyper-parameters or arrays that do not fit together.
        """
        try:
            model = cls(**params)
            model.validate_params()
        except (TypeError, ValueError) as error:
            raise ValueError(f"bad hyper-parameters ({error})") from None
        rows, cols = model.hidden_shape
        n_hidden = model.n_hidden
        dtype = np.dtype(model.dtype)
        w_bu, w_td = np.asarray(W_bu), np.asarray(W_td)
        if w_bu.shape != (n_hidden, N_INPUT) or w_td.shape != (N_INPUT, n_hidden):
            raise ValueError(
                f"W_bu {w_bu.shape} and W_td {w_td.shape} do not match hidden_shape "
                f"{model.hidden_shape}: expected ({n_hidden}, {N_INPUT}) and "
                f"({N_INPUT}, {n_hidden})"
            )
        if w_bu.dtype != dtype or w_td.dtype != dtype:
            raise ValueError(f"weights are {w_bu.dtype}/{w_td.dtype}, hyper-parameters say {dtype}")
        for name, w in (("W_bu", w_bu), ("W_td", w_td)):
            if not np.all(np.isfinite(w)) or np.any(w < 0):
                raise ValueError(f"{name} has negative or non-finite values")
        if not (isinstance(n_steps, (int, np.integer)) and n_steps >= 0):
            raise ValueError(f"n_steps must be an int >= 0, got {n_steps!r}")
        if not isinstance(generator, np.random.Generator):
            raise ValueError(
                f"generator must be a numpy.random.Generator, got {type(generator).__name__}"
            )
        model._set_state(
            w_bu.reshape(rows, cols, N_INPUT),
            w_td.T.reshape(rows, cols, N_INPUT),
            n_steps,
            generator,
        )
        return model

    def _initialise(self) -> None:
        """Draws the initial weights and computes the vocabulary codes and envelope tables."""
        self.validate_params()
        self.rng_ = np.random.default_rng(self.rng)
        rows, cols = self.hidden_shape
        dtype = np.dtype(self.dtype)
        w_bu = self.rng_.random((rows, cols, N_INPUT))
        w_bu /= np.linalg.norm(w_bu, axis=2, keepdims=True)
        w_td_t = self.init_scale * self.rng_.random((rows, cols, N_INPUT))
        self._set_state(w_bu.astype(dtype), w_td_t.astype(dtype), 0, None)

    def _set_state(self, w_bu3, w_td_t3, n_steps, rng_state) -> None:
        """Installs learned state (from ``_initialise`` and ``from_state``).

        ``w_bu3`` and ``w_td_t3`` are (rows, cols, 180) in grid order; they are stored with the
        hidden units in the order of ``_fast.Layout`` (envelope windows contiguous).
        """
        self.validate_params()
        self._build_windows()
        order = self._layout.grid_of_storage
        self._w_bu = np.ascontiguousarray(w_bu3.reshape(self.n_hidden, N_INPUT)[order])
        self._w_td_t = np.ascontiguousarray(w_td_t3.reshape(self.n_hidden, N_INPUT)[order])
        self.n_steps_ = int(n_steps)
        if rng_state is not None:
            self.rng_ = rng_state
        self.vocabulary_codes_ = encoding.encode_words(list(self.vocabulary))
        self._tables = None
        self._fast_loop = None

    def __getstate__(self) -> dict:
        """Returns the instance dict without the fast loop's views (rebuilt when needed)."""
        state = self.__dict__.copy()
        state.pop("_fast_loop", None)
        return state

    def _build_windows(self) -> None:
        """Computes the storage layout and the envelope of every winner, (768, 768) grid order."""
        sigma = float(self.envelope_sigma)
        self._layout = _fast.Layout.build(self.hidden_shape, sigma, float(self.envelope_cutoff))
        envelope = np.zeros((self.n_hidden, self.n_hidden))
        layout = self._layout
        for i, g in enumerate(layout.envelopes):
            run = layout.grid_of_storage[layout.starts[i] : layout.stops[i]]
            envelope[layout.grid_of_storage[i], run] = g
        self._envelope = envelope.astype(np.dtype(self.dtype))

    def hidden_code(self, winners) -> np.ndarray:
        """Returns the competitive codes r^c of winning units, shape (n, 768) ((768,) for one)."""
        self._check_fitted()
        return self._envelope[winners].astype(float)

    def learning_rate_factor(self, step: int) -> float:
        """Returns the schedule factor on both rates at a step: 1, then linearly to 0 over the last
        ``decay_fraction`` of ``n_steps_total``, 0 from ``n_steps_total`` on."""
        total = float(self.n_steps_total)
        remaining = total - step
        if remaining <= 0:
            return 0.0
        decay = self.decay_fraction * total
        if decay <= 0 or remaining >= decay:
            return 1.0
        return remaining / decay

    # ------------------------------------------------------------------------------------------
    # Training

    def fit(self, vision, language, motor, motor_changed=None) -> Associator:
        """Initialises the weights and trains on a stream; see ``partial_fit``. Returns self."""
        self._initialise()
        return self.partial_fit(vision, language, motor, motor_changed)

    def partial_fit(self, vision, language, motor, motor_changed=None) -> Associator:
        """Trains on ``n`` consecutive samples, one wake and ``sleeps_per_wake`` sleep phases each.

        Parameters
        ----------
        vision : array, shape (n, 96)
        language : array, shape (n, 80)
        motor : array, shape (n, 4)
        motor_changed : bool array, shape (n,), or None
            Whether the teacher's active motor unit changed at each sample (the wake rate is then
            ``motor_change_boost`` times larger). None: all False.

        Returns
        -------
        self
        """
        self.learn_inputs(encoding.assemble(vision, language, motor), motor_changed)
        return self

    def learn_inputs(self, z, motor_changed=None) -> np.ndarray:
        """Trains on ``n`` consecutive full inputs, one wake and ``sleeps_per_wake`` sleep phases
        each, and returns each wake phase's winner.

        Parameters
        ----------
        z : array, shape (n, 180)
            Full inputs [vision, language, motor] (``encoding.assemble``), each area weighted as
            the caller wants (e.g. language silent, motor times a gain); finite.
        motor_changed : bool array, shape (n,), or None
            As for ``partial_fit``.

        Returns
        -------
        winners : int64 array, shape (n,)
            The winning hidden unit of each wake phase (row-major grid index).
        """
        z = encoding.check_inputs(z, N_INPUT, "input")
        changed = check_motor_changed(motor_changed, z.shape[0])
        if not hasattr(self, "_w_bu"):
            self._initialise()
        self.validate_params()
        winners = np.empty(z.shape[0], dtype=np.int64)
        self._train(z, changed, winners)
        self._tables = None
        return winners

    def _train(self, z: np.ndarray, changed: np.ndarray, winners=None) -> None:
        """The modified wake-sleep loop, touching only the units under the truncated envelope.

        Wake (per sample): r = W_bu z, winner k = argmax r, r^c = envelope(k),
        z~ = W_td r^c, dW_td = eta' r^c (z - z~), then W_td >= 0.
        Sleep: r^s = envelope(random unit), z^s = W_td r^s, r~ = W_bu z^s,
        r~^c = envelope(argmax r~),
        dW_bu = +-epsilon' r~^c (z^s - W_bu), then W_bu >= 0 and unit-length rows.

        ``winners``, if given, an int array (n,) that receives each wake's winner (grid index).
        """
        record = None if winners is None else []
        fast = (
            self.sleep_sign == "self_organising" and self.sleeps_per_wake == 1 and self.epsilon < 1
        )
        if fast:
            self._train_fast(z, changed, record)
        else:
            self._train_general(z, changed, record)
        if winners is not None:
            winners[:] = self._layout.grid_of_storage[np.asarray(record, dtype=np.int64)]
        self.n_steps_ += z.shape[0]

    def _draw_dreams(self, n: int) -> np.ndarray:
        """Returns the random hidden centres of the sleep phases, shape (n, sleeps_per_wake),
        grid indices.

        One double per sleep phase, drawn up front: the generator's stream is then the same for any
        split of the samples into calls.
        """
        n_hidden = self.n_hidden
        u = self.rng_.random((n, int(self.sleeps_per_wake)))
        return np.minimum((u * n_hidden).astype(np.int64), n_hidden - 1)

    def _train_general(self, z: np.ndarray, changed: np.ndarray, record=None) -> None:
        """Any sleep sign and number of sleeps: straightforward per-phase updates on the windows
        (each a contiguous run of storage rows, envelope 0 outside the window)."""
        dtype = self._w_bu.dtype
        n = z.shape[0]
        w_bu, w_td = self._w_bu, self._w_td_t
        layout = self._layout
        starts, stops = layout.starts.tolist(), layout.stops.tolist()
        envelopes = [g.astype(dtype) for g in layout.envelopes]
        dreams = layout.storage_of_grid[self._draw_dreams(n)]
        factors = _fast.schedule(self, n)
        zc = z.astype(dtype)
        sign = 1.0 if self.sleep_sign == "self_organising" else -1.0
        eta, epsilon, boost = float(self.eta), float(self.epsilon), float(self.motor_change_boost)
        tiny = np.finfo(dtype).tiny
        for t in range(n):
            factor = float(factors[t])
            zt = zc[t]
            if factor == 0.0:
                if record is not None:
                    record.append(int(np.argmax(w_bu @ zt)))
                continue
            k = int(np.argmax(w_bu @ zt))
            if record is not None:
                record.append(k)
            g = envelopes[k]
            block = w_td[starts[k] : stops[k]]
            rate = eta * factor * (boost if changed[t] else 1.0)
            block += (rate * g)[:, None] * (zt - g @ block)
            np.maximum(block, 0, out=block)
            for dream in dreams[t]:
                z_sleep = envelopes[dream] @ w_td[starts[dream] : stops[dream]]
                k = int(np.argmax(w_bu @ z_sleep))
                g = envelopes[k]
                block = w_bu[starts[k] : stops[k]]
                block += (sign * epsilon * factor * g)[:, None] * (z_sleep - block)
                np.maximum(block, 0, out=block)
                norm = np.sqrt(np.einsum("ij,ij->i", block, block))
                # Rows outside the window are unchanged: leave them exactly as they are.
                norm[g == 0] = 1.0
                block /= np.maximum(norm, tiny)[:, None]

    def _train_fast(self, z: np.ndarray, changed: np.ndarray, record=None) -> None:
        """The default case (self-organising sign, one sleep per wake, epsilon < 1), equal to
        ``_train_general`` up to rounding, in fewer and cheaper numpy calls (``_fast.FastLoop``):

        - the sleep's product W_bu z^s and the next wake's W_bu z share one dense pass;
        - the sleep update (1 - a) w + a z^s of non-negative terms needs no rectification, and
          with d = a / (1 - a) its normalised result is c (w + d z^s) with
          c = (1 + 2 d w.z^s + d^2 |z^s|^2)^(-1/2) (|w| = 1): w.z^s comes from the dense pass,
          so no norms are computed, and the next wake's activations of the changed rows are
          c (w.z + d z^s.z) without another product.
        """
        loop = getattr(self, "_fast_loop", None)
        params = self.get_params()
        if loop is None or not loop.bound_to(self._w_bu, self._w_td_t, params):
            loop = _fast.FastLoop(self._w_bu, self._w_td_t, self._layout, params)
            self._fast_loop = loop
        dreams = self._layout.storage_of_grid[self._draw_dreams(z.shape[0])[:, 0]]
        zc = np.ascontiguousarray(z, dtype=self._w_bu.dtype)
        loop.run(zc, changed, dreams, _fast.schedule(self, z.shape[0]), self.n_steps_, record)

    # ------------------------------------------------------------------------------------------
    # Read-outs

    def readout_tables(self) -> ReadoutTables:
        """Returns what the network reads out at each winning unit (cached until it learns).

        With a winner-take-all hidden code, every read-out depends on the input only through the
        winning unit k: the reconstruction is W_td envelope(k). Tabulating it per unit makes batch
        read-outs one matrix product (for the winners) and a lookup.
        """
        self._check_fitted()
        if self._tables is None:
            envelope = self._envelope.astype(float)
            w_td = self.W_td_.astype(float)
            language = envelope @ w_td[LANGUAGE_SLICE].T
            motor = envelope @ w_td[MOTOR_SLICE].T
            codes = self.vocabulary_codes_
            norms = np.linalg.norm(language, axis=1, keepdims=True) * np.linalg.norm(codes, axis=1)
            scores = (language @ codes.T) / np.maximum(norms, 1e-300)
            for table in (language, motor, scores):
                table.setflags(write=False)
            self._tables = ReadoutTables(language, motor, scores)
        return self._tables

    def winners(self, vision, language=None, motor=None) -> np.ndarray:
        """Returns the winning hidden unit argmax_j (W_bu z)_j of each sample, omitted areas silent.

        Parameters
        ----------
        vision : array, shape (n, 96)
        language : array, shape (n, 80), or None
        motor : array, shape (n, 4), or None
            Each area's activations, weighted as the caller wants (any finite scale).

        Returns
        -------
        winners : int64 array, shape (n,)
            Row-major grid indices (``hidden_code`` turns them into r^c).
        """
        self._check_fitted()
        vision = encoding.check_inputs(vision, N_VISION, "vision")
        n = vision.shape[0]
        if language is not None:
            language = _same_samples(encoding.check_inputs(language, N_LANGUAGE, "language"), n)
        if motor is not None:
            motor = _same_samples(encoding.check_inputs(motor, N_MOTOR, "motor"), n)
        w_bu = self.W_bu_
        winners = np.empty(n, dtype=np.int64)
        dtype = w_bu.dtype
        w_vision = np.ascontiguousarray(w_bu[:, VISION_SLICE].T)
        w_language = np.ascontiguousarray(w_bu[:, LANGUAGE_SLICE].T)
        w_motor = np.ascontiguousarray(w_bu[:, MOTOR_SLICE].T)
        for start in range(0, n, _WINNER_CHUNK):
            stop = min(start + _WINNER_CHUNK, n)
            r = vision[start:stop].astype(dtype) @ w_vision
            if language is not None:
                r += language[start:stop].astype(dtype) @ w_language
            if motor is not None:
                r += motor[start:stop].astype(dtype) @ w_motor
            winners[start:stop] = np.argmax(r, axis=1)
        return winners

    def recognise_batch(self, vision, motor, motor_weight: float = 1.0) -> BatchRecognition:
        """Recognises the behaviour of ``n`` samples from vision (n, 96) and motor (n, 4) codes.

        The language area is omitted (silent); the language area reconstructed through W_td from the
        competitive hidden code is compared with each vocabulary word's code by cosine similarity.
        ``motor_weight`` is the read-out's weight on the motor area in the bottom-up pass that picks
        the winner (1: the paper's read-out).
        """
        self._check_fitted()
        vision = encoding.check_codes(vision, N_VISION, "vision")
        motor = encoding.check_codes(motor, N_MOTOR, "motor")
        check_motor_weight(motor_weight)
        if motor_weight != 1.0:
            motor = motor * motor_weight
        if vision.shape[0] != motor.shape[0]:
            raise ValueError(
                f"vision and motor must have the same number of samples, got "
                f"{vision.shape[0]} and {motor.shape[0]}"
            )
        winners = self.winners(vision, motor=motor)
        scores = self.readout_tables().scores[winners]
        words = np.asarray(self.vocabulary)[np.argmax(scores, axis=1)]
        return BatchRecognition(words, scores, winners)

    def recognise(self, vision, motor, motor_weight: float = 1.0) -> Recognition:
        """Recognises one sample from vision (96,) and motor (4,) codes; see ``recognise_batch``."""
        vision, motor = _single(vision, N_VISION, "vision"), _single(motor, N_MOTOR, "motor")
        batch = self.recognise_batch(vision, motor, motor_weight)
        return Recognition(str(batch.words[0]), batch.scores[0], self.hidden_code(batch.winners[0]))

    def perform_batch(self, vision, words) -> BatchPerformance:
        """Chooses motor directives for ``n`` samples from vision (n, 96) and words.

        ``words`` is one vocabulary word for all samples, a sequence of ``n`` vocabulary words
        (ValueError naming any other), or language codes (n, 80). The motor area is omitted; its
        reconstruction through W_td gives graded activations (n, 4) and the directive with the
        strongest one.
        """
        self._check_fitted()
        vision = encoding.check_codes(vision, N_VISION, "vision")
        n = vision.shape[0]
        if isinstance(words, str):
            index = word_indices([words], self.vocabulary)[0]
            language = np.broadcast_to(self.vocabulary_codes_[index], (n, N_LANGUAGE))
        elif isinstance(words, np.ndarray) and words.dtype.kind == "f":
            language = encoding.check_codes(words, N_LANGUAGE, "language")
        else:
            language = self.vocabulary_codes_[word_indices(list(words), self.vocabulary)]
        if language.shape[0] != n:
            raise ValueError(
                f"vision and words must have the same number of samples, got {n} "
                f"and {language.shape[0]}"
            )
        winners = self.winners(vision, language=language)
        motor = self.readout_tables().motor[winners]
        directives = np.asarray(DIRECTIVES)[np.argmax(motor, axis=1)]
        return BatchPerformance(directives, motor, winners)

    def perform(self, vision, word) -> Performance:
        """Chooses the motor directive for one vision code (96,) and word; see ``perform_batch``."""
        vision = _single(vision, N_VISION, "vision")
        if not isinstance(word, str):
            word = _single(word, N_LANGUAGE, "language")
        batch = self.perform_batch(vision, word)
        return Performance(
            str(batch.directives[0]), batch.motor[0], self.hidden_code(batch.winners[0])
        )


def check_motor_changed(motor_changed, n: int) -> np.ndarray:
    """Returns the per-sample motor-change flags as a bool array (n,) (None: all False); raises
    ValueError for anything else."""
    if motor_changed is None:
        return np.zeros(n, dtype=bool)
    changed = np.asarray(motor_changed)
    if changed.shape != (n,) or changed.dtype != bool:
        raise ValueError(
            f"motor_changed must be a bool array of shape ({n},), got "
            f"{changed.dtype} {changed.shape}"
        )
    return changed


def check_motor_weight(motor_weight) -> None:
    """Raises ValueError unless ``motor_weight`` (a read-out's weight on the motor area) is a
    positive finite number."""
    try:
        value = float(motor_weight)
    except (TypeError, ValueError):
        value = float("nan")
    if not (np.isfinite(value) and value > 0):
        raise ValueError(f"motor_weight must be a positive finite number, got {motor_weight!r}")


def word_indices(words, vocabulary) -> np.ndarray:
    """Returns the index in ``vocabulary`` of each of ``n`` words, shape (n,) int64; raises
    ValueError naming the unknown words and the vocabulary."""
    index = {word: i for i, word in enumerate(vocabulary)}
    unknown = sorted({repr(word) for word in words if word not in index})
    if unknown:
        raise ValueError(
            f"unknown word{'s' if len(unknown) > 1 else ''} {', '.join(unknown)}; the network's "
            f"vocabulary: {tuple(vocabulary)}"
        )
    return np.array([index[word] for word in words], dtype=np.int64)


def _same_samples(area: np.ndarray, n: int) -> np.ndarray:
    if area.shape[0] != n:
        raise ValueError(f"an area has {area.shape[0]} samples where vision has {n}")
    return area


def _single(code, width: int, name: str) -> np.ndarray:
    array = np.asarray(code, dtype=float)
    if array.shape != (width,):
        raise ValueError(f"{name} code must have shape ({width},), got {array.shape}")
    return array[None]
