"""The two devices the pipeline draws through (render/device.py's `Device`): `moderngl/`, a
standalone EGL context for the command line and the tests, and `blender/`, Blender's own
`gpu` module for the viewport, the panel and `omniwarp preview --backend blender`."""
