"""The GLSL loader (addon/render/shaders/): includes, headers, and the shipped programs.

Pure Python: no GL context. Compiling and running the shaders is tested in tests/gl.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from addon.core.errors import BackendError
from addon.render.backends.moderngl import glsl as G
from addon.render import shaders as S
from tests.support import glsl


def _write(root: Path, files: dict[str, str]) -> Path:
    for name, text in files.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")
    return root


def test_includes_are_inlined_once_in_order(tmp_path):
    root = _write(tmp_path, {
        "main.glsl": '#include "lib/a.glsl"\n#include "lib/b.glsl"\nvoid main() {}\n',
        "lib/a.glsl": "float a() { return 1.0; }\n",
        "lib/b.glsl": '#include "lib/a.glsl"\nfloat b() { return a(); }\n',
    })
    text = S.load_source("main.glsl", root)
    assert text.count("float a()") == 1  # b's include of a is dropped: already in
    assert text.index("float a()") < text.index("float b()") < text.index("void main()")
    assert "#include" not in text


def test_include_cycle_and_missing_file_are_named(tmp_path):
    root = _write(tmp_path, {
        "loop.glsl": '#include "lib/x.glsl"\n',
        "lib/x.glsl": '#include "lib/y.glsl"\n',
        "lib/y.glsl": '#include "lib/x.glsl"\n',
        "broken.glsl": '#include "lib/nope.glsl"\n',
    })
    with pytest.raises(BackendError, match="include cycle: .*x.glsl -> y.glsl -> x.glsl"):
        S.load_source("loop.glsl", root)
    with pytest.raises(BackendError, match="nope.glsl"):
        S.load_source("broken.glsl", root)


def test_an_include_path_reaches_the_shipped_library(tmp_path):
    """A test's own shader includes the shipped lib/ files through the include path: no copy."""
    root = _write(tmp_path, {"probe.frag": '#include "lib/layers.glsl"\nvoid main() {}\n',
                             "lib/local.glsl": "float local() { return 1.0; }\n"})
    text = S.load_source("probe.frag", root, include_path=(S.SHADER_DIR,))
    assert "int ow_pick_slot(" in text and "#include" not in text
    assert not (root / "lib" / "layers.glsl").exists()
    # The shader's own folder comes first; a string expands the same way.
    text = S.expand_source('#include "lib/local.glsl"\n#include "lib/spot_cone.glsl"\n', root, (S.SHADER_DIR,))
    assert "float local()" in text and "ow_spot_cone_weight" in text
    with pytest.raises(BackendError, match="nope.glsl"):
        S.expand_source('#include "lib/nope.glsl"\n', root, (S.SHADER_DIR,))


def test_stage_headers_declare_the_interface():
    iface = S.DEPTH_PROGRAM
    vertex = G.glsl_header(iface, "vertex")
    fragment = G.glsl_header(iface, "fragment")
    for header in (vertex, fragment):
        assert header.startswith(f"#version {S.GLSL_VERSION}\n")
        assert header.endswith("#line 1\n")  # compiler line numbers point into the body
        # One std140 block holds the uniforms (shaders/uniform_block.py), members by bare name.
        assert "layout(std140, binding = 0) uniform OwBlock_" in header
        for uniform in iface.uniforms:
            assert f"  {uniform.glsl_type} {uniform.name}" in header
    assert "flat out vec4 v_plane;" in vertex and "flat in vec4 v_plane;" in fragment
    assert "out vec2 v_map_xy;" in vertex and "in vec2 v_map_xy;" in fragment
    assert "layout(location = 0) in vec3 ow_position;" in vertex
    assert "layout(location = 0) out float ow_depth;" in fragment
    assert "  mat3 ow_layer_rot[6];" in G.glsl_header(S.SHADOW_TEST_PROGRAM, "fragment")
    with pytest.raises(BackendError, match="stage"):
        G.glsl_header(iface, "geometry")


def test_compute_header_declares_work_group_and_images():
    header = G.compute_header(S.SCATTER_PROGRAM)
    assert f"layout(local_size_x = {S.SCATTER_PROGRAM.local_size}) in;" in header
    assert "layout(r32ui, binding = 0) uniform uimage2D ow_counts;" in header
    assert "uniform OwBlock_" in header and "  int ow_slot_tile[6];" in header
    assert S.SCATTER_PROGRAM.groups(1) == 1
    assert S.SCATTER_PROGRAM.groups(64 * 3) == 3
    assert S.SCATTER_PROGRAM.groups(64 * 3 + 1) == 4
    assert S.SCATTER_PROGRAM.groups(0) == 1


@pytest.mark.parametrize("iface", S.PROGRAMS, ids=lambda i: i.name)
def test_every_program_loads_and_uses_only_declared_names(iface):
    vertex, fragment = G.moderngl_sources(iface)
    body = S.load_source(iface.fragment_file) + S.load_source(iface.vertex_file)
    # The exact pass's and the see-through code are compiled only into their own variants
    # (shaders.exact_of, shaders.alpha_of, shaders.veil_of, shaders.soft_of, shaders.exact_soft_of,
    # shaders.pieces_of, shaders.medium_of, shaders.haze_of, shaders.exact_soft_media_of, and the
    # readers of the exact pass's media words).
    for define in (S.EXACT_DEFINE, S.ALPHA_DEFINE, S.VEIL_DEFINE, S.SOFT_DEFINE, S.EXACT_SOFT_DEFINE, S.PIECES_DEFINE,
                   S.MEDIUM_DEFINE, S.HAZE_DEFINE, S.GRIDS_DEFINE, S.EXACT_SOFT_MEDIA_DEFINE, S.MEDIA_WORDS_DEFINE):
        if define not in iface.defines:
            body = glsl.without_blocks(body, "#ifdef", define)
    declared = {u.name for u in iface.uniforms} | set(iface.samplers) | {name for _, name in iface.images}
    used = set(re.findall(r"\b(ow_[a-z_0-9]+)\b", body))
    # Every ow_ name a body reads is either declared here or defined in the GLSL itself.
    types = (r"void|float|vec[234]|mat[234]|int|uint|bool|ivec[234]|uvec[234]|struct|OwBlend|OwLightView"
             r"|const int|const float|const vec4")
    defined = set(re.findall(rf"\b(?:{types})\s+(ow_[a-z_0-9]+)", body))
    missing = used - declared - defined - {n for _, n in iface.vertex_in} - {n for _, n in iface.fragment_out}
    assert not missing, f"{iface.name} reads undeclared {sorted(missing)}"
    assert vertex.startswith("#version") and fragment.startswith("#version")


@pytest.mark.parametrize("iface", S.COMPUTE_PROGRAMS, ids=lambda i: i.name)
def test_every_compute_program_loads(iface):
    source = G.moderngl_compute_source(iface)
    assert source.startswith("#version")
    assert "void main()" in source and "#include" not in source


def test_every_program_has_its_own_name():
    """Backends cache compiled programs by name: two variants of one name would share one."""
    names = [iface.name for iface in (*S.PROGRAMS, *S.COMPUTE_PROGRAMS)]
    assert len(set(names)) == len(names), sorted(n for n in set(names) if names.count(n) > 1)
