"""OmniWarp Shadows: Blender extension entry point.

Blender imports this file as the extension package and calls `register()` /
`unregister()`. All code lives in `addon/`; the bpy layer is `addon/blender/`.
Imports happen inside the functions so that importing this file (pytest may do
so while collecting, since the repository root is a package) needs no bpy.
"""


def register() -> None:
    """Register the extension's Blender classes (called by Blender)."""
    from .addon.blender import registration

    registration.register()


def unregister() -> None:
    """Unregister the extension's Blender classes (called by Blender)."""
    from .addon.blender import registration

    registration.unregister()
