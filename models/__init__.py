"""MJCF models of the PeopleBot and its arena, shipped as package data (``peoplebot_models``)."""

import pathlib

MODELS_DIR = pathlib.Path(__file__).resolve().parent
