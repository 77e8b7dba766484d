"""The paper's figures 3, 5, 6 and 7 for a fitted ``Associator`` (matplotlib, Agg backend).

Each function draws one figure, writes it to ``path`` (format from the suffix) and returns the path.
Hidden-layer maps are drawn as the 16 x 48 grid, dark for strong weights, as in the paper, each with
its colour bar.
"""

from __future__ import annotations

import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from associator import encoding  # noqa: E402
from associator.encoding import DIRECTIVES, LANGUAGE_SLICE, MOTOR_SLICE, N_FEATURES  # noqa: E402
from associator.network import Associator  # noqa: E402


def _save(fig, path) -> str:
    path = os.fspath(path)
    fig.savefig(path, dpi=120, bbox_inches="tight")
    plt.close(fig)
    return path


def fig3_word_codes(path, words=encoding.WORDS) -> str:
    """Fig. 3: the 4 x 20 language codes of ``words`` with their phonemes."""
    table = encoding.phoneme_table()
    fig, axes = plt.subplots(
        len(words), 1, figsize=(7, 1.9 * len(words)), squeeze=False, constrained_layout=True
    )
    for ax, word in zip(axes[:, 0], words, strict=True):
        phonemes = encoding.pronounce(word)
        code = encoding.encode_word(word).reshape(encoding.N_PHONEMES_PER_WORD, N_FEATURES)
        ax.imshow(code, cmap="Greys", vmin=0, vmax=1, aspect="equal")
        ax.set_yticks(range(encoding.N_PHONEMES_PER_WORD))
        ax.set_yticklabels([f"/{p}/" for p in phonemes] + [""] * (4 - len(phonemes)))
        ax.set_xticks(range(N_FEATURES))
        ax.set_xticklabels(table.features if ax is axes[-1, 0] else [], rotation=90, fontsize=7)
        ax.set_title(f"'{word}'", fontsize=9, loc="left")
    return _save(fig, path)


def _grid(ax, values: np.ndarray, shape, title: str, label: str = "weight") -> None:
    """Draws ``values`` on the hidden grid in ``ax`` with a colour bar labelled ``label``."""
    image = ax.imshow(values.reshape(shape), cmap="Greys", interpolation="nearest")
    ax.set_xticks([])
    ax.set_yticks([])
    ax.set_title(title, fontsize=8)
    bar = ax.figure.colorbar(image, ax=ax, fraction=0.03, pad=0.02)
    bar.ax.tick_params(labelsize=6)
    bar.set_label(label, fontsize=6)


def select_language_units(model: Associator) -> list[int]:
    """Returns four language-area units (0..79): for each of the first three vocabulary words the
    unit active in that word's code only (the one with the strongest top-down weights), then a
    unit active in every word."""
    codes = model.vocabulary_codes_ > 0.5
    strength = model.W_td_[LANGUAGE_SLICE].sum(axis=1)
    chosen = []
    for i in range(min(3, codes.shape[0])):
        only = codes[i] & ~np.delete(codes, i, axis=0).any(axis=0)
        candidates = np.flatnonzero(only) if only.any() else np.flatnonzero(codes[i])
        chosen.append(int(candidates[np.argmax(strength[candidates])]))
    common = np.flatnonzero(codes.all(axis=0))
    if common.size:
        chosen.append(int(common[np.argmax(strength[common])]))
    return chosen


def _language_unit_name(unit: int) -> str:
    row, feature = divmod(unit, N_FEATURES)
    return f"phoneme {row + 1}, {encoding.phoneme_table().features[feature]}"


def fig5_language_weights(model: Associator, path, units=None) -> str:
    """Fig. 5: W_td to four language units drawn on the hidden grid (default
    ``select_language_units``: one unit per word, then one all words activate)."""
    units = select_language_units(model) if units is None else list(units)
    codes = model.vocabulary_codes_
    w_td = model.W_td_[LANGUAGE_SLICE]
    fig, axes = plt.subplots(1, len(units), figsize=(3.6 * len(units), 1.7), squeeze=False)
    for ax, unit in zip(axes[0], units, strict=True):
        active = [w for w, c in zip(model.vocabulary, codes, strict=True) if c[unit] > 0.5]
        label = ", ".join(f"'{w}'" for w in active) if len(active) < len(codes) else "all words"
        _grid(ax, w_td[unit], model.hidden_shape, f"{label}\n({_language_unit_name(unit)})")
    return _save(fig, path)


def fig6_motor_weights(model: Associator, path) -> str:
    """Fig. 6: W_td to the four motor units drawn on the hidden grid."""
    w_td = model.W_td_[MOTOR_SLICE]
    fig, axes = plt.subplots(1, len(DIRECTIVES), figsize=(3.6 * len(DIRECTIVES), 1.7))
    for ax, name, weights in zip(axes, DIRECTIVES, w_td, strict=True):
        _grid(ax, weights, model.hidden_shape, name.replace("_", " "))
    return _save(fig, path)


def hidden_sums(
    model: Associator, recognition: dict, performance: dict, correct_only: bool = True
) -> tuple[dict, dict]:
    """Returns per-word sums of the competitive hidden code r^c, shape (768,) each.

    Args:
      recognition: word -> (vision (n, 96), motor (n, 4)) observed while the teacher performs it.
      performance: word -> vision (n, 96) seen while the student performs it on instruction.
      correct_only: sum recognition only over samples recognised as that word (as in the paper).
    """
    n_hidden = model.n_hidden
    recognised, performed = {}, {}
    for word, (vision, motor) in recognition.items():
        batch = model.recognise_batch(vision, motor)
        winners = batch.winners[batch.words == word] if correct_only else batch.winners
        counts = np.bincount(winners, minlength=n_hidden).astype(float)
        recognised[word] = counts @ model.hidden_code(np.arange(n_hidden))
    for word, vision in performance.items():
        batch = model.perform_batch(vision, word)
        counts = np.bincount(batch.winners, minlength=n_hidden).astype(float)
        performed[word] = counts @ model.hidden_code(np.arange(n_hidden))
    return recognised, performed


def fig7_hidden_activations(
    model: Associator, path, recognition: dict, performance: dict, correct_only: bool = True
) -> str:
    """Fig. 7: hidden activations summed a) while recognising and b) while performing, per word.

    Arguments as in ``hidden_sums``; the words of ``recognition`` are drawn in its order.
    """
    recognised, performed = hidden_sums(model, recognition, performance, correct_only)
    words = list(recognition)
    fig, axes = plt.subplots(2, len(words), figsize=(3.6 * len(words), 3.6), squeeze=False)
    for col, word in enumerate(words):
        _grid(
            axes[0, col],
            recognised[word],
            model.hidden_shape,
            f"a) recognising '{word}'",
            "summed activation",
        )
        if word in performed:
            _grid(
                axes[1, col],
                performed[word],
                model.hidden_shape,
                f"b) performing '{word}'",
                "summed activation",
            )
        else:
            axes[1, col].axis("off")
    return _save(fig, path)
