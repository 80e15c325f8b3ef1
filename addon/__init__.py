"""OmniWarp Shadows: all Python of the extension.

Layers (imports run one way, top to bottom):
  blender/, cli.py      bpy UI and the command line
  render/, reference/   the shadow pipeline with its backends; Cycles ground truth
  core/                 numpy only
"""
