"""The GPU's planning statistics (sample_stats.comp) against the numpy oracle (core.samples)."""
from __future__ import annotations

import numpy as np
import pytest

from addon.core import samples as S
from addon.core.errors import InputError
from addon.core.presets import build_preset
from addon.core.scene import CameraSpec, LightSpec
from addon.render.frame import ViewSamples
from addon.render.pipeline import ShadowPipeline
from tests.support.oracle import view_samples

pytestmark = pytest.mark.gl


def _gpu_stats(backend, light: LightSpec, samples: ViewSamples) -> S.SampleStats:
    pipe = ShadowPipeline(backend)
    pipe._upload_samples(light, samples)
    raw = pipe._reduce_samples(light, samples)
    return S.Reduction.decode(raw, samples.camera, light, samples.shape).stats(samples.camera, samples.shape)


def _bin_width(stats: S.SampleStats, camera: CameraSpec) -> float:
    lo, hi = stats.depth
    log = S.log_bins(camera, stats.depth)
    return float(S.bin_edge(S.HIST_BINS, stats.depth, log) - S.bin_edge(S.HIST_BINS - 1, stats.depth, log)) \
        if log else (hi - lo) / S.HIST_BINS


def _check_agree(gpu: S.SampleStats, host: S.SampleStats, camera: CameraSpec, light: LightSpec) -> None:
    assert gpu.count == host.count
    assert gpu.window == host.window
    assert gpu.sides == host.sides and gpu.faces == host.faces
    if host.count == 0:
        assert gpu.depth is None and gpu.box is None
        return
    scale = host.reach() + 1.0
    # The GPU's range and box hold the exact ones, and are wider by rounding only.
    assert gpu.depth[0] <= host.depth[0] and gpu.depth[1] >= host.depth[1]
    span = host.depth[1] - host.depth[0] + abs(host.depth[1])
    offset = abs(S.depth_axis(camera, light)[1])
    assert np.allclose(gpu.depth, host.depth, rtol=0, atol=4 * S.ROUNDING * (3 * scale + offset))
    assert np.all(gpu.box[0] <= host.box[0]) and np.all(gpu.box[1] >= host.box[1])
    assert np.allclose(gpu.box[0], host.box[0], atol=1e-5 * scale)
    assert np.allclose(gpu.box[1], host.box[1], atol=1e-5 * scale)
    # The percentile cut agrees to a couple of bins, and both hold the exact percentiles.
    width = _bin_width(host, camera)
    assert abs(gpu.cull_depth[0] - host.cull_depth[0]) <= 2.5 * width + 1e-5 * span
    assert abs(gpu.cull_depth[1] - host.cull_depth[1]) <= 2.5 * width + 1e-5 * span


@pytest.mark.slow
@pytest.mark.parametrize("preset", ["room_omni", "room_hemi", "courtyard", "stress_light_inside_object",
                                    "stress_scale_large", "stress_scale_small", "stress_one_texel", "spot_street"])
def test_gpu_statistics_match_the_oracle_on_presets(gl_backend, preset):
    scene = build_preset(preset, (96, 72))
    samples, _, _ = view_samples(scene)
    gpu = _gpu_stats(gl_backend, scene.light, samples)
    host = S.measure(scene.camera, scene.light, samples.positions, samples.hit)
    _check_agree(gpu, host, scene.camera, scene.light)
    assert gpu.count > 0


@pytest.mark.parametrize("seed", range(6))
def test_gpu_statistics_match_the_oracle_on_random_samples(gl_backend, seed):
    """Random sparse samples, far from the origin or not, hemi or omni, ortho or not."""
    rng = np.random.default_rng(seed)
    width, height = 40, 30
    offset = rng.choice([0.0, 1e3, 1e5])
    eye = np.eye(4)
    eye[:3, 3] = (offset, 0.0, 5.0)
    ortho = seed % 3 == 2
    camera = (CameraSpec(eye, 0.0, (width, height), window=(-3.0, 3.0, -2.25, 2.25), ortho=True) if ortho
              else CameraSpec(eye, 50.0, (width, height)))
    depth = rng.uniform(1.0, 20.0, (height, width))
    ndc = np.stack(np.meshgrid((np.arange(width) + 0.5) / width * 2 - 1,
                               1 - (np.arange(height) + 0.5) / height * 2), axis=-1)
    positions = camera.world_points(ndc.reshape(-1, 2), depth.ravel()).reshape(height, width, 3)
    hit = rng.random((height, width)) < (0.02 if seed == 0 else 0.5)
    hit[:, : seed] = False  # a sky border, so the window narrows
    light_matrix = np.eye(4)
    light_matrix[:3, 3] = (offset + rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-15, 3))
    light = LightSpec("hemi" if seed % 2 else "omni", light_matrix)
    samples = ViewSamples(positions, np.tile([0.0, 0.0, 1.0], (height, width, 1)), hit, camera)
    gpu = _gpu_stats(gl_backend, light, samples)
    _check_agree(gpu, S.measure(camera, light, positions, hit), camera, light)


def test_no_sample_gives_no_range(gl_backend):
    scene = build_preset("room_omni", (16, 12))
    samples, _, _ = view_samples(scene)
    empty = ViewSamples(samples.positions, samples.normals, np.zeros_like(samples.hit), scene.camera)
    gpu = _gpu_stats(gl_backend, scene.light, empty)
    assert gpu.count == 0 and gpu.depth is None and gpu.cull_depth is None and gpu.box is None
    assert gpu.window == S.FULL_WINDOW


def test_percentile_cut_holds_the_exact_percentiles():
    """The histogram cut is never narrower than np.percentile, and at most a few bins wider."""
    rng = np.random.default_rng(3)
    for log in (False, True):
        depths = np.exp(rng.normal(1.0, 1.0, 5000)) if log else rng.normal(0.0, 4.0, 5000)
        depth = (float(depths.min()), float(depths.max()))
        hist = np.bincount(S.depth_bins(depths, depth, log), minlength=S.HIST_BINS)
        low, high = S.percentile_cut(hist, depth, log, 0.5)
        exact = np.percentile(depths, [0.5, 99.5])
        assert low <= exact[0] and high >= exact[1]
        assert depth[0] <= low and high <= depth[1]
        below = np.mean(depths < low)
        above = np.mean(depths > high)
        assert below <= 0.005 and above <= 0.005
        assert below > 0.002 and above > 0.002  # the cut does leave the stray samples out


@pytest.mark.parametrize("preset, size", [("room_omni", (96, 72)), ("courtyard", (160, 120)),
                                          ("stress_scale_small", (64, 48))])
def test_gpu_cut_bins_are_the_numpy_bins_of_its_histogram(gl_backend, preset, size):
    """Pass 2 finds the percentile cut's bins in the histogram pass 1 left in the image, as
    core.samples.cut_bins finds them there, and says how the bins are spaced; the host reads
    only the fields."""
    scene = build_preset(preset, size)
    samples, _, _ = view_samples(scene)
    gpu = _gpu_stats(gl_backend, scene.light, samples)
    image = gl_backend.device.read(gl_backend.samples.stats, "R32UI").ravel()
    hist = image[S.STAT_COUNT:S.STAT_COUNT + S.HIST_BINS]
    reduction = S.Reduction.decode(image, scene.camera, scene.light, samples.shape)
    assert int(hist.sum()) == gpu.count > 0
    assert reduction.cut == S.cut_bins(hist)
    assert reduction.cut_log == S.log_bins(scene.camera, gpu.depth)
    assert gpu.cull_depth == S.cut_range(reduction.cut, gpu.depth, reduction.cut_log)


def test_the_cut_group_covers_the_histogram_in_whole_chunks():
    """Pass 2 is one work group of CUT_CHUNKS invocations, each over HIST_BINS / CUT_CHUNKS
    bins, with its chunk sums in the texels after the histogram."""
    from addon.render.shaders import SAMPLE_STATS_PROGRAM

    assert S.HIST_BINS % S.CUT_CHUNKS == 0
    assert SAMPLE_STATS_PROGRAM.local_size == S.CUT_CHUNKS
    assert S.STAT_TEXELS == S.STAT_COUNT + S.HIST_BINS + S.CUT_CHUNKS


def test_cut_ranks_are_exact_integer_ranks():
    """The integer ranks (the GPU's arithmetic) are floor(p (n - 1) / 100) and
    ceil((100 - p) (n - 1) / 100) taken exactly, up to millions of samples; a percentile
    off the 1/CUT_STEPS grid is refused."""
    from fractions import Fraction

    for percentile in (0.5, 0.1, 5.0, 50.0):
        p = Fraction(str(percentile)) / 100
        for n in [*range(1, 2000), 4096 * 4096, 3_840 * 2_160 + 7]:
            k_lo, k_hi = S.cut_ranks(n, percentile)
            assert k_lo == (p * (n - 1)).__floor__()
            assert k_hi == ((1 - p) * (n - 1)).__ceil__()
    with pytest.raises(InputError):
        S.cut_ranks(100, 0.25)


@pytest.mark.parametrize("layout", ["one_bin", "first_bin", "last_bin", "chunk_edges", "spread"])
def test_the_cut_group_finds_numpys_bins_in_any_histogram(gl_backend, layout):
    """Pass 2 alone over a histogram written into the reduction image: the bins of the
    cut's ranks are np.searchsorted's, wherever the samples sit (one bin, the ends, the
    edges of the group's chunks, everywhere)."""
    from addon.render.shaders import SAMPLE_STATS_PROGRAM, STATS_PASSES

    rng = np.random.default_rng(len(layout))
    hist = np.zeros(S.HIST_BINS, dtype=np.uint32)
    chunk = S.HIST_BINS // S.CUT_CHUNKS
    if layout == "one_bin":
        hist[517] = 4000
    elif layout == "first_bin":
        hist[0] = 3
    elif layout == "last_bin":
        hist[-1] = 9000
        hist[3] = 1
    elif layout == "chunk_edges":
        hist[chunk - 1::chunk] = rng.integers(1, 50, S.CUT_CHUNKS)
        hist[chunk::chunk] = rng.integers(1, 50, S.CUT_CHUNKS - 1)
    else:
        hist[:] = rng.integers(0, 30, S.HIST_BINS)
    image = np.zeros(S.STAT_TEXELS, dtype=np.uint32)
    image[S.STAT_FIELDS.index("count")] = hist.sum()
    image[S.STAT_COUNT:S.STAT_COUNT + S.HIST_BINS] = hist
    device = gl_backend.device
    with device.bound():
        stats = device.texture((S.STAT_TEXELS, 1), "R32UI", image)
        out = device.texture((S.STAT_COUNT, 1), "R32UI")
        positions = device.texture((1, 1), "RGBA32F")  # not read by pass 2
        uniforms = {"ow_light_rot": np.eye(3), "ow_view_axis": np.array([0.0, 0.0, 1.0]), "ow_view_offset": 0.0,
                    "ow_hemi": 0, "ow_ortho": 1, "ow_stats_pass": STATS_PASSES["cut"]}
        device.dispatch(SAMPLE_STATS_PROGRAM, uniforms, {"ow_positions": positions},
                        {"ow_stats": stats, "ow_stats_out": out}, 1)
        fields = device.read(out, "R32UI").ravel()
        device.free(stats, out, positions)
    got = (int(fields[S.STAT_FIELDS.index("cut_lo")]) - 1, int(fields[S.STAT_FIELDS.index("cut_hi")]) - 1)
    assert got == S.cut_bins(hist)
