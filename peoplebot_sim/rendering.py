"""Offscreen rendering of the simulator's cameras (headless through EGL by default).

Camera frames for vision render without shadows: on the CPU, shadows cost several times the rest of
the frame (docs/design.md, "Benchmarks"). Videos may turn them on.

A ``FrameRenderer`` owns its OpenGL context on a thread of its own. On the caller's thread it would
make its context current behind ``dm_control``'s back, which believes its own still is (it keeps
track per thread) and then renders the environment's camera observables into nothing: a head-mode
student filmed for a video saw black frames and never localised itself.
"""

from __future__ import annotations

import concurrent.futures

import mujoco
import numpy as np


class FrameRenderer:
    """Renders RGB frames of named cameras of a physics.

    Args:
      physics: a ``dm_control`` physics.
      width, height: frame size in pixels (above 640x480 the model needs ``offwidth``/``offheight``;
        the arena model allows up to 1280x960).
      shadows: render shadows (slow on the CPU; off for vision).
      antialias: 4x multisampling for videos (the model's default is none, for vision speed).
      shadow_size: the shadow map's side in pixels (None: the model's; videos take 1024, about
        half the cost of the model's 4096 on the CPU).

    Use as a context manager, or call ``close()``: an EGL context left open errors at exit.
    """

    def __init__(
        self,
        physics,
        width: int = 320,
        height: int = 240,
        shadows: bool = False,
        antialias: bool = False,
        shadow_size: int | None = None,
    ):
        model = physics.model.ptr
        max_w, max_h = model.vis.global_.offwidth, model.vis.global_.offheight
        if not (isinstance(width, (int, np.integer)) and 1 <= width <= max_w):
            raise ValueError(f"width must be an integer in [1, {max_w}] pixels, got {width!r}")
        if not (isinstance(height, (int, np.integer)) and 1 <= height <= max_h):
            raise ValueError(f"height must be an integer in [1, {max_h}] pixels, got {height!r}")
        self._physics = physics
        self._renderer = None
        self._thread = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="renderer")

        def make() -> mujoco.Renderer:
            samples, size = model.vis.quality.offsamples, model.vis.quality.shadowsize
            if antialias:
                model.vis.quality.offsamples = 4
            if shadow_size is not None:
                model.vis.quality.shadowsize = int(shadow_size)
            try:
                return mujoco.Renderer(model, height, width)
            finally:
                model.vis.quality.offsamples, model.vis.quality.shadowsize = samples, size

        self._renderer = self._thread.submit(make).result()
        self._shadows = bool(shadows)
        self.width, self.height = int(width), int(height)

    def _camera_id(self, camera: str) -> int:
        model = self._physics.model
        try:
            return model.name2id(camera, "camera")
        except ValueError:
            names = [model.id2name(i, "camera") for i in range(model.ncam)]
            raise ValueError(f"unknown camera {camera!r}; allowed: {', '.join(names)}") from None

    def render(self, camera, out: np.ndarray | None = None) -> np.ndarray:
        """Returns an (height, width, 3) uint8 RGB frame of ``camera`` (a model camera's name, or a
        ``mujoco.MjvCamera`` such as ``peoplebot_sim.viewpoints``') at the current state."""
        if not isinstance(camera, mujoco.MjvCamera):
            camera = self._camera_id(camera)

        def render() -> np.ndarray:
            self._renderer.update_scene(self._physics.data.ptr, camera)
            self._renderer.scene.flags[mujoco.mjtRndFlag.mjRND_SHADOW] = self._shadows
            return self._renderer.render(out=out)

        return self._thread.submit(render).result()

    def close(self) -> None:
        if self._renderer is not None:
            self._thread.submit(self._renderer.close).result()
            self._renderer = None
        self._thread.shutdown()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
