"""Writes ``associator/data/phonemes.csv``: 46 British English phonemes x 20 binary features.

Development tool (needs ``panphon``, a dev dependency); the associator only reads the CSV it writes.

The inventory is the 44 phonemes of Received Pronunciation (24 consonants, 12 monophthongs, 8
diphthongs) plus the two weak vowels of Wells' Longman Pronunciation Dictionary, /i/ (happY) and /u/
(inflUence), written in SAMPA, the notation of the paper's words (/g @U/, /p I k/, /l I f t/).

Features: 18 of PanPhon's 24 articulatory features for each segment's IPA form, '+' -> 1 and
'0'/'-' -> 0. Dropped: five that never distinguish two English phonemes (``sg``, ``cg``,
``velaric``, ``hitone``, ``hireg``) and one that only duplicates another contrast (``delrel``:
affricates already differ from stops by ``strid`` and from fricatives by ``cont``). A diphthong is
one phoneme, but PanPhon reads it as two segments; its row is its first element's features with
``long`` set (RP diphthongs pattern with long vowels) plus two off-glide features read from the
second element: ``offglide_hi`` (its ``hi``) and ``offglide_back`` (its ``back``), 0 for every
other phoneme. The script checks that all 46 rows differ.

Run: ``python tools/make_phoneme_table.py`` from the repository root.
"""

from __future__ import annotations

import pathlib

import panphon

# SAMPA -> IPA, in table order.
INVENTORY = {
    "p": "p",
    "b": "b",
    "t": "t",
    "d": "d",
    "k": "k",
    "g": "ɡ",
    "tS": "t͡ʃ",
    "dZ": "d͡ʒ",
    "f": "f",
    "v": "v",
    "T": "θ",
    "D": "ð",
    "s": "s",
    "z": "z",
    "S": "ʃ",
    "Z": "ʒ",
    "h": "h",
    "m": "m",
    "n": "n",
    "N": "ŋ",
    "l": "l",
    "r": "ɹ",
    "w": "w",
    "j": "j",
    "I": "ɪ",
    "e": "e",
    "{": "æ",
    "Q": "ɒ",
    "V": "ʌ",
    "U": "ʊ",
    "@": "ə",
    "i:": "iː",
    "3:": "ɜː",
    "A:": "ɑː",
    "O:": "ɔː",
    "u:": "uː",
    "eI": "eɪ",
    "aI": "aɪ",
    "OI": "ɔɪ",
    "@U": "əʊ",
    "aU": "aʊ",
    "I@": "ɪə",
    "e@": "eə",
    "U@": "ʊə",
    "i": "i",
    "u": "u",
}
PANPHON_FEATURES = (
    "syl",
    "son",
    "cons",
    "cont",
    "lat",
    "nas",
    "strid",
    "voi",
    "ant",
    "cor",
    "distr",
    "lab",
    "hi",
    "lo",
    "back",
    "round",
    "tense",
    "long",
)
FEATURES = PANPHON_FEATURES + ("offglide_hi", "offglide_back")
OUTPUT = pathlib.Path(__file__).resolve().parents[1] / "associator" / "data" / "phonemes.csv"


def _binary(table: panphon.FeatureTable, segment) -> dict[str, int]:
    values = dict(zip(table.names, segment.numeric(), strict=True))
    return {name: int(values[name] > 0) for name in PANPHON_FEATURES}


def phoneme_rows() -> dict[str, tuple[int, ...]]:
    """Returns SAMPA symbol -> 20 binary features, in ``INVENTORY`` order."""
    table = panphon.FeatureTable()
    rows = {}
    for sampa, ipa in INVENTORY.items():
        segments = table.word_fts(ipa)
        if len(segments) == 1:
            row = _binary(table, segments[0])
            row.update(offglide_hi=0, offglide_back=0)
        elif len(segments) == 2:
            row = _binary(table, segments[0])
            second = _binary(table, segments[1])
            row.update(long=1, offglide_hi=second["hi"], offglide_back=second["back"])
        else:
            raise RuntimeError(f"{sampa} /{ipa}/ gave {len(segments)} PanPhon segments")
        rows[sampa] = tuple(row[name] for name in FEATURES)
    if len(set(rows.values())) != len(rows):
        raise RuntimeError("two phonemes share a feature row")
    return rows


def main() -> None:
    rows = phoneme_rows()
    lines = [
        "# 46 British English phonemes (SAMPA) x 20 binary features; written by "
        "tools/make_phoneme_table.py from PanPhon " + _panphon_version() + ".",
        "sampa,ipa," + ",".join(FEATURES),
    ]
    for sampa, row in rows.items():
        lines.append(f"{sampa},{INVENTORY[sampa]}," + ",".join(str(v) for v in row))
    OUTPUT.write_text("\n".join(lines) + "\n", encoding="utf-8")
    print(f"wrote {OUTPUT} ({len(rows)} phonemes x {len(FEATURES)} features)")


def _panphon_version() -> str:
    from importlib.metadata import version

    return version("panphon")


if __name__ == "__main__":
    main()
