"""nmbake for Blender: bake normal maps (and the rest of nmbake's map set)
from the scene's objects, through one live `nmbake serve` session.

The panel is in the render properties; README "Baking from Blender".
"""

bl_info = {
    "name": "nmbake",
    "author": "nmbake",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > nmbake",
    "description": "Bake normal maps from high to low meshes with nmbake",
    "category": "Render",
}

from . import ui  # noqa: E402


def register():
    ui.register()


def unregister():
    ui.unregister()
