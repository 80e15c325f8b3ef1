"""The moderngl backend's GLSL headers (the `shaders` package holds the interfaces and the loader;
blender_gpu.py builds Blender's): a `#version` block of declarations before each shared
stage body."""
from __future__ import annotations

from pathlib import Path

from ....core.errors import BackendError
from .uniforms import BLOCK_BINDING
from ...shaders import (GLSL_VERSION, SHADER_DIR, ComputeInterface, ProgramInterface, image_type, load_source,
                      program_defines)
from ...shaders.uniform_block import UniformBlock


def _uniform_block(iface: ProgramInterface | ComputeInterface) -> list[str]:
    """The program's uniforms: one std140 block at BLOCK_BINDING (none when it has none)."""
    block = UniformBlock.of(iface)
    if not block.members:
        return []
    return [block.glsl_block().replace("layout(std140)", f"layout(std140, binding = {BLOCK_BINDING})", 1)]


def glsl_header(iface: ProgramInterface, stage: str) -> str:
    """Declarations for a plain-GLSL backend (moderngl) of one stage ('vertex' or 'fragment')."""
    if stage not in ("vertex", "fragment"):
        raise BackendError(f"unknown shader stage {stage!r}")
    lines = [f"#version {GLSL_VERSION}"]
    lines += [f"#define {k} {v}" for k, v in program_defines(iface).items()]
    lines += _uniform_block(iface)
    lines += [f"uniform sampler2D {name};" for name in iface.samplers]
    for var in iface.varyings:
        qualifier = "flat " if var.flat else ""
        direction = "out" if stage == "vertex" else "in"
        lines.append(f"{qualifier}{direction} {var.glsl_type} {var.name};")
    if stage == "vertex":
        lines += [f"layout(location = {i}) in {t} {n};" for i, (t, n) in enumerate(iface.vertex_in)]
    else:
        lines += [f"layout(location = {i}) out {t} {n};" for i, (t, n) in enumerate(iface.fragment_out)]
        lines += [f"layout({fmt}, binding = {unit}) uniform {image_type(fmt)} {name};"
                  for unit, (fmt, name) in enumerate(iface.images)]
    return "\n".join(lines) + "\n#line 1\n"


def compute_header(iface: ComputeInterface) -> str:
    """Declarations of a compute program for a plain-GLSL backend (moderngl)."""
    lines = [f"#version {GLSL_VERSION}"]
    lines += [f"#define {k} {v}" for k, v in program_defines(iface).items()]
    lines.append(f"layout(local_size_x = {iface.local_size}) in;")
    lines += _uniform_block(iface)
    lines += [f"uniform sampler2D {name};" for name in iface.samplers]
    coherent = "coherent " if iface.coherent else ""
    lines += [f"layout({fmt}, binding = {unit}) {coherent}uniform {image_type(fmt)} {name};"
              for unit, (fmt, name) in enumerate(iface.images)]
    return "\n".join(lines) + "\n#line 1\n"


def moderngl_compute_source(iface: ComputeInterface, shader_dir: Path = SHADER_DIR) -> str:
    """Complete compute source for moderngl."""
    return compute_header(iface) + load_source(iface.compute_file, shader_dir)


def moderngl_sources(iface: ProgramInterface, shader_dir: Path = SHADER_DIR) -> tuple[str, str]:
    """Complete vertex and fragment sources for moderngl."""
    vertex = glsl_header(iface, "vertex") + load_source(iface.vertex_file, shader_dir)
    fragment = glsl_header(iface, "fragment") + load_source(iface.fragment_file, shader_dir)
    return vertex, fragment
