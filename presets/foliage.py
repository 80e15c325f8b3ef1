"""Foliage under a point light: leaf cards, a chain-link fence, a curtain and an opaque box.

Every see-through material is a white Principled BSDF whose Alpha comes from an image
(the leaves, the fence's tiling wire) or is a constant (the curtain, alpha 0.5), as an
artist builds them; the Blender scene packs the images (reference/blender_scene.py).
"""
import math

import numpy as np

DESCRIPTION = ("A tree of 90 alpha-cut leaf cards, a chain-link fence with a tiling alpha texture, a curtain "
               "of alpha 0.5 and an opaque box on a 16x16 m ground; omni light above.")
STRESSES = ("see-through materials: shadows of cut-outs (exact alpha at the texel ray's crossing), a "
            "fractional shadow (the curtain), sub-texel holes (the fence)")

LEAVES = 90


def _leaf_image(size: int = 64) -> np.ndarray:
    """A leaf: an ellipse pointed at both ends, with a stem; 0 or 1 at every texel."""
    v, u = (np.indices((size, size)) + 0.5) / size
    x, y = (u - 0.5) / 0.46, (v - 0.5) / 0.30
    blade = (x * x + y * y * (1.0 + 1.5 * x * x)) <= 1.0
    stem = (np.abs(v - 0.5) < 0.03) & (u < 0.1)
    return (blade | stem).astype(np.float32)


def _wire_image(size: int = 32) -> np.ndarray:
    """One diamond of chain-link: two diagonal wires, a hole between."""
    v, u = (np.indices((size, size)) + 0.5) / size
    width = 0.09
    wire = (np.abs(((u + v) % 1.0) - 0.5) > 0.5 - width) | (np.abs(((u - v) % 1.0) - 0.5) > 0.5 - width)
    return wire.astype(np.float32)


def _card(centre: np.ndarray, normal: np.ndarray, spin: float, width: float, height: float) -> np.ndarray:
    """Four corners of a card around `centre`, facing `normal`, turned by `spin`."""
    normal = normal / np.linalg.norm(normal)
    helper = np.array([0.0, 0.0, 1.0]) if abs(normal[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    a = np.cross(helper, normal)
    a /= np.linalg.norm(a)
    b = np.cross(normal, a)
    a, b = math.cos(spin) * a + math.sin(spin) * b, -math.sin(spin) * a + math.cos(spin) * b
    du, dv = 0.5 * width * a, 0.5 * height * b
    return np.array([centre - du - dv, centre + du - dv, centre + du + dv, centre - du + dv])


def build(b) -> None:
    b.plane("ground", (0.0, 0.0, 0.0), 16.0, 16.0)
    # The tree: a trunk and a crown of leaf cards on a sphere, facing out, tilted at random.
    b.box("trunk", (-2.0, 1.5, 1.1), (0.25, 0.25, 2.2))
    leaf = b.alpha_image("leaf", _leaf_image(), "linear", "clip")
    rng = np.random.default_rng(25)
    crown = np.array([-2.0, 1.5, 3.0])
    for i in range(LEAVES):
        direction = rng.normal(size=3)
        direction /= np.linalg.norm(direction)
        centre = crown + direction * rng.uniform(0.5, 1.3) * np.array([1.0, 1.0, 0.7])
        normal = direction + rng.normal(scale=0.6, size=3)
        b.quad(f"leaf_{i:02d}", _card(centre, normal, rng.uniform(0.0, math.pi), 0.55, 0.38), alpha=leaf)
    # A chain-link fence, 7 x 1.8 m, a diamond every 0.2 m (its holes a few map texels wide).
    x0, x1, y, top = -1.0, 6.0, 4.0, 1.8
    b.quad("fence", [(x1, y, 0.0), (x0, y, 0.0), (x0, y, top), (x1, y, top)],
           tiles=((x1 - x0) / 0.2, top / 0.2), alpha=b.alpha_image("chain_link", _wire_image(), "linear", "repeat"))
    # A curtain of alpha 0.5 hanging across the light's way to the ground at x > 3.5.
    b.quad("curtain", [(3.5, -1.0, 0.2), (3.5, 1.0, 0.2), (3.5, 1.0, 2.4), (3.5, -1.0, 2.4)],
           alpha=b.constant_alpha("curtain", 0.5))
    # The opaque control.
    b.box("crate", (1.0, -2.5, 0.6), (1.2, 1.2, 1.2), rotate_z_deg=20.0)
    b.point_light((0.0, 0.0, 7.0))
    b.camera((7.0, 8.0, 7.5), (-0.8, -0.8, 0.0), fov_deg=65.0)
