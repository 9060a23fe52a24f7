"""The `Physics` every environment here runs on: dm_control's, with GL loaded on demand."""

from __future__ import annotations

from dm_control import mjcf

from franka_composer.headless_gl import load_deferred_backend


class Physics(mjcf.Physics):
    """`mjcf.Physics` that loads the GL backend `headless_gl` deferred before making its
    first rendering context (`render()`, `contexts` and the viewer all come through here)."""

    def _make_rendering_contexts(self):
        load_deferred_backend()
        return super()._make_rendering_contexts()
