"""The associator network of Elshaw, Weber, Zochios and Wermter: imitation through vision, motor
control and language (section III of the paper), in numpy.

Modules: ``encoding`` (the 180 input units), ``network`` (``Associator``: wake-sleep training and
the recognise/perform read-outs), ``hierarchy`` (``HierarchicalAssociator``: a word layer above
the paper's network), ``persistence`` (``.npz`` save/load), ``figures`` (Figs. 3, 5, 6, 7) and
``synthetic`` (a kinematic teacher stream for tests and benchmarks). This package never
imports mujoco, dm_control or cv2, so it runs unchanged on a real robot's data.
"""

from associator.encoding import DIRECTIVES, WORDS, VisionEncoder, encode_motor, encode_word
from associator.network import Associator
from associator.persistence import load, save

__all__ = [
    "DIRECTIVES",
    "WORDS",
    "Associator",
    "VisionEncoder",
    "encode_motor",
    "encode_word",
    "load",
    "save",
]
