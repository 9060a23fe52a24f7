"""The world the robot works in: a floor plane at z = 0, lights and a workspace camera.

The robot base sits at the world origin on the floor, as in the paper. The slide task uses
the same arena with a slippery floor (`friction=0.04`).
"""

from __future__ import annotations

from dm_control import composer

from franka_composer.contacts import FLOOR_SOLMIX, make_stiff

#: Camera framing the arm, the object square and the slide goals out to x = 1.15 m, looking
#: at (0.6, 0, 0.2) from the front right: (pos, xyaxes, vertical field of view in degrees).
WORKSPACE_CAMERA = dict(pos=(1.7, -0.95, 0.9), xyaxes=(0.654, 0.757, 0.0, -0.328, 0.284, 0.901),
                        fovy=40)
#: Camera looking straight down on the workspace.
TOP_CAMERA = dict(pos=(0.75, 0.0, 1.6), xyaxes=(0.0, -1.0, 0.0, 1.0, 0.0, 0.0))

#: The arena's cameras, by name.
CAMERAS = ("workspace", "top")

#: Largest frame `physics.render` can return (offscreen buffer), pixels.
MAX_RENDER_SIZE = 1024
#: The rendered frames' width and height (pixels) where none is given.
RENDER_SIZE = 480


class FloorArena(composer.Arena):
    """A floor with a given sliding friction, lit from above, with two named cameras.

    Rendering is kept cheap on software GL: a small checker texture, a tiny gradient sky, no
    reflections, no multisampling, two lights without shadows.
    """

    def _build(self, name: str = "floor_arena", friction: float = 1.0,
               floor_rgb=((0.82, 0.82, 0.80), (0.70, 0.70, 0.68))) -> None:
        super()._build(name=name)
        root = self._mjcf_root
        root.visual.__getattr__("global").offwidth = MAX_RENDER_SIZE
        root.visual.__getattr__("global").offheight = MAX_RENDER_SIZE
        root.visual.quality.shadowsize = 0
        # No multisampling: on software GL 4x MSAA quadruples the cost of a 480x480 frame.
        root.visual.quality.offsamples = 0
        # A plain gradient sky (a 64-pixel builtin texture) instead of black, nearly free.
        root.asset.add("texture", name="sky", type="skybox", builtin="gradient",
                       rgb1=(0.75, 0.82, 0.90), rgb2=(0.35, 0.42, 0.52), width=64, height=64)
        checker = root.asset.add(
            "texture", name="floor_checker", type="2d", builtin="checker", width=64, height=64,
            rgb1=floor_rgb[0], rgb2=floor_rgb[1],
        )
        material = root.asset.add(
            "material", name="floor", texture=checker, texrepeat=(8, 8), reflectance=0.0
        )
        self._floor = root.worldbody.add(
            "geom", name="floor", type="plane", size=(2.5, 2.5, 0.1), material=material,
            friction=(friction, 0.005, 0.0001),
        )
        make_stiff(self._floor, solmix=FLOOR_SOLMIX)
        root.worldbody.add("light", name="key", pos=(0.6, -0.6, 2.0), dir=(0, 0.3, -1),
                           directional=True, castshadow=False, diffuse=(0.5, 0.5, 0.5))
        root.worldbody.add("light", name="fill", pos=(0.6, 0.6, 2.0), dir=(0, -0.3, -1),
                           directional=True, castshadow=False, diffuse=(0.3, 0.3, 0.3))
        self._workspace_camera = root.worldbody.add(
            "camera", name="workspace", **WORKSPACE_CAMERA)
        # Rendered by its name alone (the env's camera="top"), so no property holds it.
        root.worldbody.add("camera", name="top", fovy=45, **TOP_CAMERA)

    @property
    def floor(self):
        """The floor geom; its top surface is z = 0."""
        return self._floor

    @property
    def surface_height(self) -> float:
        """Height (m) of the surface objects rest on."""
        return 0.0

    @property
    def workspace_camera(self):
        return self._workspace_camera
