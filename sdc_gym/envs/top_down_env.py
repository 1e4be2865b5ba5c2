"""The rendering plumbing both loop envs share: render modes, frame rate, ``render()``, ``close()``.

:class:`TopDownRenderEnv` is a ``gymnasium.Env`` whose ``render()`` draws a top-down view
with a :class:`~sdc_gym.render.top_down.TopDownRenderer`. A subclass

* calls :meth:`TopDownRenderEnv._init_render_mode` early in its constructor (a bad
  ``render_mode`` fails before any other work), and :meth:`TopDownRenderEnv._set_render_fps`
  once it knows how long a step lasts (``steps_per_action`` physics frames): the ``human``
  window then runs in real time at ``1 / step_s`` steps per second
  (``metadata["render_fps"]``);
* implements :meth:`TopDownRenderEnv._make_renderer` (built lazily on the first
  ``render()``, so pygame is imported only by envs that render) and
  :meth:`TopDownRenderEnv._render_scene` (the frame's scene; raises ``RuntimeError``
  before ``reset()``).

``render()`` with ``render_mode=None`` warns and returns None (Gymnasium's convention);
``"rgb_array"`` returns a (height, width, 3) uint8 frame; ``"human"`` shows it and returns
None.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, ClassVar

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

if TYPE_CHECKING:
    from sdc_gym.render.top_down import TopDownRenderer

RENDER_MODES = ["human", "rgb_array"]
RENDER_CONFIG_DEFAULTS: dict[str, Any] = {
    "render_width": 600,              # px
    "render_height": 600,             # px
    "render_pixels_per_meter": 5.0,   # zoom of the top-down view
}
"""The config keys every rendered env takes (spread into its ``DEFAULT_CONFIG``)."""


class TopDownRenderEnv(gym.Env):
    """Base of the envs rendered top-down; see the module doc."""

    metadata: ClassVar[dict[str, Any]] = {"render_modes": RENDER_MODES, "render_fps": 50}
    config: dict[str, Any]  # the resolved config (with the RENDER_CONFIG_DEFAULTS keys)

    def _init_render_mode(self, render_mode: str | None) -> None:
        """Check and store ``render_mode`` (one of ``metadata["render_modes"]`` or None)."""
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} "
                             f"or None, got {render_mode!r}")
        self.render_mode = render_mode
        self._renderer: TopDownRenderer | None = None

    def _set_render_fps(self, step_s: float) -> None:
        """Set this instance's ``metadata["render_fps"]`` to real time for steps of
        ``step_s`` seconds (the class's metadata is left alone)."""
        self.metadata = {**self.metadata, "render_fps": round(1.0 / step_s)}

    def _renderer_options(self) -> dict[str, Any]:
        """The renderer's frame size, zoom and frame rate, from the config and metadata."""
        config = self.config
        return {"width": config["render_width"], "height": config["render_height"],
                "pixels_per_meter": config["render_pixels_per_meter"],
                "render_fps": self.metadata["render_fps"]}

    def _make_renderer(self) -> TopDownRenderer:
        """The renderer, built on the first ``render()``."""
        raise NotImplementedError

    def _render_scene(self) -> Any:
        """The scene of the current state; ``RuntimeError`` before ``reset()``."""
        raise NotImplementedError

    def render(self) -> NDArray[np.uint8] | None:
        if self.render_mode is None:
            gym.logger.warn("render() called without a render_mode; pass render_mode= "
                            "'rgb_array' or 'human' to gym.make")
            return None
        scene = self._render_scene()
        if self._renderer is None:
            self._renderer = self._make_renderer()
        if self.render_mode == "rgb_array":
            return self._renderer.render_rgb(scene)
        self._renderer.render_human(scene)
        return None

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
