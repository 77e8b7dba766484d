"""Typed results of a run: the records each stage produces, serialised once (``to_json``) into the run
folder's ``state.json`` and ``results.json``, and read back (``from_json``) to render ``results.md``.

Word-keyed and row-keyed tables (``{"go": ...}``) are data; everything else is a named field.
"""

from __future__ import annotations

import dataclasses
import platform
from importlib import metadata

import numpy as np

from associator.encoding import WORDS
from imitation.performance import ROWS

#: The version of ``results.json``'s layout; raised whenever a key changes meaning or place.
SCHEMA_VERSION = 1


@dataclasses.dataclass(frozen=True)
class ConfusionTable:
    """A recognition confusion table: ``counts[true][recognised]`` over ``WORDS``, shape (3, 3)."""

    counts: tuple

    @classmethod
    def from_counts(cls, counts: np.ndarray) -> ConfusionTable:
        counts = np.asarray(counts)
        if counts.shape != (len(WORDS), len(WORDS)):
            raise ValueError(f"counts must have shape (3, 3), got {counts.shape}")
        return cls(tuple(tuple(int(v) for v in row) for row in counts))

    def totals(self) -> dict:
        """Returns the number of steps per true word."""
        return {t: sum(self.counts[i]) for i, t in enumerate(WORDS)}

    def fraction(self, true: str, recognised: str) -> float | None:
        """Returns the fraction of ``true``'s steps recognised as ``recognised`` (None: no steps)."""
        row = self.counts[WORDS.index(true)]
        total = sum(row)
        return row[WORDS.index(recognised)] / total if total else None

    def correct(self, word: str) -> float | None:
        """Returns the fraction of ``word``'s steps recognised correctly (the diagonal)."""
        return self.fraction(word, word)

    def to_json(self) -> dict:
        return {
            "confusion": {t: {r: self.fraction(t, r) for r in WORDS} for t in WORDS},
            "counts": self.totals(),
            "counts_matrix": {
                t: {r: self.counts[i][j] for j, r in enumerate(WORDS)} for i, t in enumerate(WORDS)
            },
        }

    @classmethod
    def from_json(cls, data: dict) -> ConfusionTable:
        matrix = data["counts_matrix"]
        return cls(tuple(tuple(int(matrix[t][r]) for r in WORDS) for t in WORDS))


@dataclasses.dataclass(frozen=True)
class PaperTable:
    """A confusion table given as fractions and counts per true word (the paper's Table I)."""

    confusion: dict
    counts: dict

    def correct(self, word: str) -> float:
        return self.confusion[word][word]

    def to_json(self) -> dict:
        return {"confusion": self.confusion, "counts": self.counts}


#: The paper's Table I: rows performing, columns recognised (fractions) and the total counts.
PAPER_TABLE_I = PaperTable(
    confusion={
        "go": {"go": 0.5451, "pick": 0.4426, "lift": 0.0123},
        "pick": {"go": 0.0308, "pick": 0.9647, "lift": 0.0045},
        "lift": {"go": 0.0089, "pick": 0.1223, "lift": 0.8688},
    },
    counts={"go": 746211, "pick": 111495, "lift": 142195},
)


@dataclasses.dataclass(frozen=True)
class ErrorSummary:
    """The median and 95th percentile of an error, in the unit its name gives."""

    median: float
    p95: float

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> ErrorSummary:
        return cls(float(data["median"]), float(data["p95"]))


@dataclasses.dataclass(frozen=True)
class CameraRecognition:
    """Recognition on steps watched through a camera: from the student's estimates and, paired,
    from the truth on the same steps; the tracked teacher's position error (paper's read-out)."""

    steps: int
    seen_fraction: float
    vision: ConfusionTable
    truth_same_steps: ConfusionTable
    teacher_position_error_cm: ErrorSummary | None = None

    def to_json(self) -> dict:
        out = {
            "steps": self.steps,
            "seen_fraction": self.seen_fraction,
            "vision": self.vision.to_json(),
            "truth_same_steps": self.truth_same_steps.to_json(),
        }
        if self.teacher_position_error_cm is not None:
            out["teacher_position_error_cm"] = self.teacher_position_error_cm.to_json()
        return out

    @classmethod
    def from_json(cls, data: dict) -> CameraRecognition:
        error = data.get("teacher_position_error_cm")
        return cls(
            int(data["steps"]),
            float(data["seen_fraction"]),
            ConfusionTable.from_json(data["vision"]),
            ConfusionTable.from_json(data["truth_same_steps"]),
            None if error is None else ErrorSummary.from_json(error),
        )


#: The read-outs of the paper's network: its own, and the motor area weighted by 3 in the
#: bottom-up pass (name -> the read-out's motor weight).
READOUTS = {"paper": 1.0, "motor_weighted": 3.0}

# Recognition fields, named as their keys in state.json (``truth`` is the paper's read-out).
_TRUTH_KEYS = (
    "truth",
    "truth_motor_weighted",
    "truth_hierarchical",
    "truth_hierarchical_over_time",
)
_CAMERA_KEYS = (
    "vision",
    "vision_motor_weighted",
    "vision_hierarchical",
    "vision_hierarchical_over_time",
)


@dataclasses.dataclass(frozen=True)
class RecognitionResult:
    """The recognition stage: Table I on the test stream for each read-out, and the same on steps
    watched through the camera (camera modes)."""

    truth: ConfusionTable
    truth_motor_weighted: ConfusionTable
    truth_hierarchical: ConfusionTable | None = None
    truth_hierarchical_over_time: ConfusionTable | None = None
    vision: CameraRecognition | None = None
    vision_motor_weighted: CameraRecognition | None = None
    vision_hierarchical: CameraRecognition | None = None
    vision_hierarchical_over_time: CameraRecognition | None = None

    def to_json(self) -> dict:
        out = {"readouts": dict(READOUTS)}
        for name in (*_TRUTH_KEYS, *_CAMERA_KEYS):
            value = getattr(self, name)
            if value is not None:
                out[name] = value.to_json()
        return out

    @classmethod
    def from_json(cls, data: dict) -> RecognitionResult:
        values = {}
        for name in _TRUTH_KEYS:
            if name in data:
                values[name] = ConfusionTable.from_json(data[name])
        for name in _CAMERA_KEYS:
            if name in data:
                values[name] = CameraRecognition.from_json(data[name])
        return cls(**values)


@dataclasses.dataclass(frozen=True)
class TrialRecord:
    """One performance trial: its row, policy, start (world x m, y m, yaw rad) and the wall its
    success refers to; the verdict, duration, whether the robot touched anything, where it ended,
    the median error of the student's own-pose estimate (cm; None when it had none), the
    verdict's reason in one line, the own-pose error's 95th percentile (cm), the median of
    the estimate's 95% position ellipse's semi-major axis (cm; None without a covariance: the
    landmark filter's only) and the own heading's absolute error, median and 95th percentile
    (deg)."""

    row: str
    policy: str
    index: int
    start: tuple
    wall: str
    success: bool
    seconds: float
    touched: bool
    end_pose: tuple
    own_pose_error_cm_median: float | None
    reason: str
    own_pose_error_cm_p95: float | None = None
    own_position_ellipse95_cm_median: float | None = None
    own_heading_error_deg_median: float | None = None
    own_heading_error_deg_p95: float | None = None

    def to_json(self) -> dict:
        out = dataclasses.asdict(self)
        out["start"], out["end_pose"] = list(self.start), list(self.end_pose)
        return out

    @classmethod
    def from_json(cls, data: dict) -> TrialRecord:
        return cls(**{**data, "start": tuple(data["start"]), "end_pose": tuple(data["end_pose"])})


@dataclasses.dataclass(frozen=True)
class SuccessRate:
    """The success rate of one policy on one row, over its trials."""

    success_rate: float
    successes: int
    trials: int
    touched: int
    mean_seconds: float
    own_pose_error_cm_median: float | None

    @classmethod
    def of(cls, trials: list[TrialRecord]) -> SuccessRate:
        successes = sum(t.success for t in trials)
        errors = [
            t.own_pose_error_cm_median for t in trials if t.own_pose_error_cm_median is not None
        ]
        return cls(
            successes / len(trials),
            successes,
            len(trials),
            sum(t.touched for t in trials),
            float(np.mean([t.seconds for t in trials])),
            float(np.median(errors)) if errors else None,
        )

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> SuccessRate:
        return cls(**data)


@dataclasses.dataclass(frozen=True)
class Fig4Trace:
    """Where the student ended performing one word from the paper's Fig. 4 start."""

    end_pose: tuple
    touched: bool
    seconds: float

    def to_json(self) -> dict:
        return {"end_pose": list(self.end_pose), "touched": self.touched, "seconds": self.seconds}

    @classmethod
    def from_json(cls, data: dict) -> Fig4Trace:
        return cls(tuple(data["end_pose"]), bool(data["touched"]), float(data["seconds"]))


@dataclasses.dataclass(frozen=True)
class PerformanceResult:
    """The performance stage: ``rates[row][policy]`` (None where the policy has no trials on the
    row) and the Fig. 4 runs per word."""

    rates: dict
    fig4: dict

    def rate(self, row: str, policy: str) -> SuccessRate | None:
        return self.rates.get(row, {}).get(policy)

    def to_json(self) -> dict:
        out = {
            row: {p: (None if r is None else r.to_json()) for p, r in policies.items()}
            for row, policies in self.rates.items()
        }
        out["fig4"] = {word: trace.to_json() for word, trace in self.fig4.items()}
        return out

    @classmethod
    def from_json(cls, data: dict) -> PerformanceResult:
        rates = {
            row: {
                p: (None if r is None else SuccessRate.from_json(r)) for p, r in data[row].items()
            }
            for row in ROWS
            if row in data
        }
        fig4 = {word: Fig4Trace.from_json(v) for word, v in data.get("fig4", {}).items()}
        return cls(rates, fig4)


@dataclasses.dataclass(frozen=True)
class StreamSummary:
    """A generated teacher stream: its file (relative to the run folder), its length and the share
    of its steps per word."""

    path: str
    steps: int
    time_share: dict

    def to_json(self) -> dict:
        return dataclasses.asdict(self)

    @classmethod
    def from_json(cls, data: dict) -> StreamSummary:
        return cls(data["path"], int(data["steps"]), dict(data["time_share"]))


@dataclasses.dataclass(frozen=True)
class StreamsResult:
    """The streams stage: the training and test streams, and the run folder they were copied
    from (``--reuse-from``), if any."""

    train: StreamSummary
    test: StreamSummary
    reused_from: str | None = None

    def to_json(self) -> dict:
        out = {"train": self.train.to_json(), "test": self.test.to_json()}
        if self.reused_from is not None:
            out["reused_from"] = self.reused_from
        return out

    @classmethod
    def from_json(cls, data: dict) -> StreamsResult:
        return cls(
            StreamSummary.from_json(data["train"]),
            StreamSummary.from_json(data["test"]),
            data.get("reused_from"),
        )


@dataclasses.dataclass(frozen=True)
class NetworkSummary:
    """A trained network: its file (relative to the run folder), the samples it learned from and its
    hyper-parameters (``get_params()``, tuples as lists)."""

    network: str
    steps: int
    params: dict

    def to_json(self) -> dict:
        return {"network": self.network, "steps": self.steps, "params": self.params}

    @classmethod
    def from_json(cls, data: dict) -> NetworkSummary:
        return cls(data["network"], int(data["steps"]), dict(data["params"]))


@dataclasses.dataclass(frozen=True)
class LearningResult:
    """The learning stage: the paper's network and, if trained, the hierarchical associator."""

    paper: NetworkSummary
    hierarchical: NetworkSummary | None = None
    reused_from: str | None = None

    def to_json(self) -> dict:
        out = self.paper.to_json()
        if self.hierarchical is not None:
            out["hierarchical"] = self.hierarchical.to_json()
        if self.reused_from is not None:
            out["reused_from"] = self.reused_from
        return out

    @classmethod
    def from_json(cls, data: dict) -> LearningResult:
        hierarchical = data.get("hierarchical")
        return cls(
            NetworkSummary.from_json(data),
            None if hierarchical is None else NetworkSummary.from_json(hierarchical),
            data.get("reused_from"),
        )


@dataclasses.dataclass(frozen=True)
class Results:
    """What ``results.json`` holds: the run's results beside the paper's, and how they were made."""

    vision: str
    motor_source: str
    seed: int
    recognition: RecognitionResult | None
    performance: PerformanceResult | None
    streams: StreamsResult | None
    learning: LearningResult | None
    figures: dict | None
    videos: list | None
    seconds_per_stage: dict
    config: dict
    versions: dict

    @property
    def total_seconds(self) -> float:
        return float(sum(self.seconds_per_stage.values()))

    def to_json(self) -> dict:
        rec = self.recognition
        recognition = {}
        if rec is not None:
            truth = rec.truth.to_json()
            recognition = {
                "confusion": truth["confusion"],
                "counts": truth["counts"],
                "counts_matrix": truth["counts_matrix"],
                "paper": PAPER_TABLE_I.to_json(),
                "motor_weighted": rec.truth_motor_weighted.to_json(),
                "hierarchical": _json_or_none(rec.truth_hierarchical),
                "hierarchical_over_time": _json_or_none(rec.truth_hierarchical_over_time),
                "readouts": dict(READOUTS),
            }
            for name in _CAMERA_KEYS:
                if getattr(rec, name) is not None:
                    recognition[name] = getattr(rec, name).to_json()
        performance = {}
        fig4 = None
        perf = self.performance
        if perf is not None:
            for row in ("go", "pick", "lift", "pick_other_wall"):
                if perf.rate(row, "student") is not None:
                    performance[row] = perf.rate(row, "student").to_json()
            performance["hierarchical"] = {
                row: perf.rate(row, "student_hierarchical").to_json()
                for row in ("go", "pick", "lift", "pick_other_wall")
                if perf.rate(row, "student_hierarchical") is not None
            }
            performance["teacher_reference"] = {
                row: perf.rate(row, "teacher").to_json()
                for row in ("go", "pick", "lift")
                if perf.rate(row, "teacher") is not None
            }
            fig4 = {word: trace.to_json() for word, trace in perf.fig4.items()}
        return {
            "schema_version": SCHEMA_VERSION,
            "paper": "Elshaw, Weber, Zochios and Wermter: an associator network approach to robot "
            "learning by imitation through vision, motor control and language",
            "vision": self.vision,
            "motor_source": self.motor_source,
            "seed": self.seed,
            "recognition": recognition,
            "performance": performance,
            "fig4": fig4,
            "streams": None if self.streams is None else self.streams.to_json(),
            "learning": None if self.learning is None else self.learning.to_json(),
            "figures": self.figures,
            "videos": self.videos,
            "seconds_per_stage": self.seconds_per_stage,
            "total_seconds": self.total_seconds,
            "config": self.config,
            "versions": self.versions,
        }


def _json_or_none(record):
    return None if record is None else record.to_json()


def package_versions() -> dict:
    """Returns the versions of Python and of the packages the results depend on."""
    names = ("peoplebot-imitation", "mujoco", "dm-control", "numpy", "opencv-python-headless")
    out = {"python": platform.python_version()}
    for name in names:
        try:
            out[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            out[name] = None
    return out
