"""numpy-only core: scene description, light frames, projections, planning,
tessellation and metrics. Nothing here imports bpy or a GL binding."""
