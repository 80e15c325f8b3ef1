"""The sidebar's comparison tool (addon.blender.comparison).

Measuring draws with Blender's `gpu`, and this pytest process owns moderngl (one GL
owner per process, docs/design.md section 3), so every measurement in Blender runs in a
child process (tests/support/comparison_worker.py). The parent renders the Cycles
reference into a shared cache folder ($OMNIWARP_CACHE, set for both processes) and
measures the same rows with the command line's moderngl path, which must give the
same error figures. Input checks, the preset builder, export and drawing run here:
they touch no GPU.
"""
from __future__ import annotations

import csv
import json
import math
from pathlib import Path
from types import SimpleNamespace

import pytest

bpy = pytest.importorskip("bpy", reason="the comparison panel needs bpy (scripts/setup_env.sh installs it)")

from addon import compare  # noqa: E402
from addon.core import methods as method_registry  # noqa: E402
from addon.blender import compare_job, compare_ops, compare_props, compare_ui, registration  # noqa: E402
from addon.core.presets import DEFAULT_PRESET, available_presets  # noqa: E402
from tests.support.checks import expect  # noqa: E402
from tests.support.cli_run import env_with, run_python  # noqa: E402

pytestmark = pytest.mark.blender

WORKER = Path(__file__).resolve().parents[1] / "support" / "comparison_worker.py"
CAMERA = (160, 120)
METHODS = ("dpsm", "dpsm+notw")
RESOLUTION = 512
TIME_FACTOR = 5.0  # Blender gpu vs moderngl total time per frame: same work, timing noise only


class Reports:
    """Stands in for Operator.report on a fake operator."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str]] = []

    def __call__(self, kinds: set[str], message: str) -> None:
        self.items.extend((kind, message) for kind in kinds)

    def errors(self) -> list[str]:
        return [message for kind, message in self.items if kind == "ERROR"]


# ----------------------------------------------------------------------------
# the measurement: parent (moderngl, the CLI's path) and child (Blender gpu)
# ----------------------------------------------------------------------------
@pytest.fixture(scope="module")
def shared_cache(tmp_path_factory: pytest.TempPathFactory):
    """$OMNIWARP_CACHE for this module, and the room_omni reference rendered into it."""
    from addon.reference.cache import CACHE_ENV, load_or_capture

    folder = tmp_path_factory.mktemp("comparison_cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv(CACHE_ENV, str(folder))
        reference = load_or_capture(DEFAULT_PRESET, CAMERA)
        yield folder, reference


@pytest.fixture(scope="module")
def worker(shared_cache, tmp_path_factory: pytest.TempPathFactory) -> tuple[dict, Path]:
    """Run the child once: exec run, exports, modal run, current-scene run, unregister."""
    folder, _ = shared_cache
    out = tmp_path_factory.mktemp("comparison_worker")
    proc = run_python(WORKER, out, CAMERA[0], CAMERA[1], env=env_with(OMNIWARP_CACHE=folder), timeout=300)
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-3000:]
    return json.loads((out / "worker.json").read_text()), out


def test_compare_fills_results_and_plot(worker) -> None:
    report, _ = worker
    assert report["exec_result"] == ["FINISHED"]
    rows = report["ui_rows"]
    assert [(r["method"], r["resolution"]) for r in rows] == [(m, RESOLUTION) for m in METHODS]
    for row in rows:
        for key in ("error_pct", "false_shadow_pct", "false_lit_pct", "total_ms", "maps_ms", "test_ms"):
            assert math.isfinite(row[key]), key
        assert row["error_pct"] == pytest.approx(row["false_shadow_pct"] + row["false_lit_pct"], abs=1e-4)
        assert 0.0 <= row["error_pct"] < 5.0
        assert row["total_ms"] > 0.0 and row["passes"] >= 1
        expect(row, "mismatch_exists", method=row["method"], mismatch_image=row["mismatch_image"])
        assert row["preset"] == DEFAULT_PRESET
    assert rows[1]["analysis_ms"] > 0.0  # NoTW runs the analysis pass
    plot = report["plot"]
    assert plot["name"] == compare_props.PLOT_IMAGE_NAME
    assert plot["size"][0] > 100 and plot["size"][1] > 100
    assert plot["pixels"] == plot["size"][0] * plot["size"][1] * 4 and plot["std"] > 0.01
    mismatch = report["mismatch"]  # the first row is selected, its mismatch image loaded
    assert mismatch["name"] == compare_props.MISMATCH_IMAGE_NAME
    assert mismatch["size"] == list(CAMERA) and mismatch["std"] > 0.0
    assert mismatch["filepath"] == rows[0]["mismatch_image"]
    assert report["progress"] == pytest.approx(1.0) and "2 rows measured" in report["status"], \
        (report["progress"], report["status"])
    expect(report, "not running_after")
    for row in report["rows"]:
        assert row["backend"] == "blender-gpu" and row["frames"] == 1
        assert row["camera_size"] == list(CAMERA)


def test_modal_loop_steps_and_cancels(worker) -> None:
    """Each timer tick does one step; other events pass through; Esc keeps the partial rows,
    releases the backend and lets a new run start."""
    report, _ = worker
    cancel = report["modal_cancel"]
    assert cancel["poll_while_running"] is False
    assert cancel["ticks"] == [["PASS_THROUGH"], ["PASS_THROUGH"]]
    assert cancel["mouse"] == ["PASS_THROUGH"]
    assert cancel["esc"] == ["CANCELLED"]
    assert cancel["rows"] == 1 and cancel["status"].startswith("Cancelled after 1 of 2 rows")
    expect(cancel, "backend_released", "not running_after", "poll_after", run="cancelled")
    full = report["modal_full"]
    assert full["results"] == [["PASS_THROUGH"], ["FINISHED"]]  # reference, then the only row
    assert full["rows"] == 1 and full["progress"] == pytest.approx(1.0)
    expect(full, "backend_released", "not running_after", run="full")
    assert [kind for kind, _ in full["reports"]] == ["INFO"]


def test_current_scene_matches_its_preset(worker) -> None:
    """The preset built into a new scene, measured as the current scene (captured anew),
    gives the preset's error."""
    report, _ = worker
    assert report["build"] == ["FINISHED"]
    expect(report, "build_new_scene", "current_copied_settings")
    assert report["current_result"] == ["FINISHED"]
    (row,) = report["current_rows"]
    assert row["method"] == "dpsm" and row["preset"].startswith("OmniWarp_room_omni")
    assert row["error_pct"] == pytest.approx(report["ui_rows"][0]["error_pct"], abs=1e-9)


def test_unregister_frees_module_state(worker) -> None:
    report, _ = worker
    expect(report, "state_freed", "pointer_removed")


def test_exported_json_and_csv(worker) -> None:
    report, out = worker
    assert report["exports"] == {"json": ["FINISHED"], "csv": ["FINISHED"]}
    rows = json.loads((out / "results.json").read_text())
    assert [r["method"] for r in rows] == list(METHODS)
    for row in rows:
        assert {"preset", "method", "resolution", "error_pct", "time_ms", "passes", "backend"} <= row.keys()
        assert set(row["time_ms"]) >= {"total", "analysis", "shadow_maps", "shadow_test"}
    with (out / "results.csv").open(newline="", encoding="utf-8") as stream:
        lines = list(csv.DictReader(stream))
    assert [line["method"] for line in lines] == list(METHODS)
    for line, row in zip(lines, rows):
        assert "time_ms" not in line
        assert float(line["time_ms.total"]) == pytest.approx(row["time_ms"]["total"])
        assert float(line["error_pct"]) == pytest.approx(row["error_pct"])
        assert json.loads(line["layers"]) == row["layers"]


@pytest.mark.gl
def test_numbers_match_the_command_line(worker, shared_cache, gl_backend) -> None:
    """The CLI's path (run_row on moderngl) on the same cached reference: equal error,
    times within timing noise."""
    from addon.render.pipeline import ShadowPipeline

    report, _ = worker
    _, reference = shared_cache
    options = compare.CompareOptions(methods=METHODS, resolutions=(RESOLUTION,), frames=1)
    pipeline = ShadowPipeline(gl_backend)
    for ours, method in zip(report["rows"], METHODS):
        cli = compare.run_row(pipeline, reference, DEFAULT_PRESET, method, RESOLUTION, options, None)
        assert cli["backend"] != ours["backend"]
        for key in ("error_pct", "false_shadow_pct", "false_lit_pct"):
            assert abs(cli[key] - ours[key]) < 1e-9, (method, key, cli[key], ours[key])
        assert cli["evaluated_pixels"] == ours["evaluated_pixels"]
        assert cli["passes"] == ours["passes"] and cli["triangles_drawn"] == ours["triangles_drawn"]
        ratio = ours["time_ms"]["total"] / cli["time_ms"]["total"]
        assert 1.0 / TIME_FACTOR < ratio < TIME_FACTOR, (method, ours["time_ms"], cli["time_ms"])


# ----------------------------------------------------------------------------
# in this process: no GPU work
# ----------------------------------------------------------------------------
@pytest.fixture
def registered(monkeypatch: pytest.MonkeyPatch):
    """The extension registered without its runtime modules; the scene's tool settings reset after."""
    monkeypatch.setattr(registration, "RUNTIME_MODULES", ())
    registration.unregister()
    registration.register()
    scene = bpy.context.scene
    yield scene.omniwarp_compare
    scene.property_unset("omniwarp_compare")
    registration.unregister()


def _untick_all(settings) -> None:
    for method in method_registry.pipeline_methods():
        setattr(settings, compare_props.method_prop(method), False)


def test_registered_classes_and_pointer(registered) -> None:
    assert all(cls.is_registered for cls in registration.TOOL_CLASSES)
    assert isinstance(registered, compare_props.OMNIWARP_PG_comparison)
    assert [cls.__name__ for cls in registration.TOOL_CLASSES] == [
        "OMNIWARP_PG_result_row", "OMNIWARP_PG_comparison", "OMNIWARP_OT_build_preset", "OMNIWARP_OT_compare",
        "OMNIWARP_OT_export_results", "OMNIWARP_UL_results", "OMNIWARP_PT_compare"]
    for cls in registration.TOOL_CLASSES:
        if issubclass(cls, bpy.types.Operator):
            assert cls.bl_idname == "omniwarp." + cls.__name__.removeprefix("OMNIWARP_OT_")
    assert compare_ui.OMNIWARP_PT_compare.bl_category == "OmniWarp"
    assert compare_ui.OMNIWARP_PT_compare.bl_label == "Compare methods"
    assert registered.source == "PRESET" and registered.preset == DEFAULT_PRESET
    assert registered.resolutions == "512,1024" and registered.frames == 2
    assert registered.export_path == "//omniwarp_results.json"
    assert compare_props.selected_methods(registered) == compare.DEFAULT_METHODS


def test_method_checkboxes_cover_every_method(registered) -> None:
    rna = compare_props.OMNIWARP_PG_comparison.bl_rna.properties
    names = {compare_props.method_prop(m) for m in method_registry.pipeline_methods()}
    assert {"use_dpsm", "use_cube", "use_dpsm_notw", "use_cube_notw", "use_dpsm_rtw", "use_cube_rtw"} <= names
    for method in method_registry.pipeline_methods():
        prop = rna[compare_props.method_prop(method)]
        assert prop.type == "BOOLEAN" and prop.name == method


@pytest.mark.parametrize("group", ["OMNIWARP_PG_comparison", "OMNIWARP_PG_result_row"])
def test_every_property_has_a_description(registered, group: str) -> None:
    for prop in getattr(compare_props, group).bl_rna.properties:
        if prop.identifier in ("rna_type", "name"):
            continue
        assert len(prop.description) > 20, f"{group}.{prop.identifier} needs a tooltip"
        if prop.type == "ENUM" and not prop.is_enum_flag:
            for item in prop.enum_items:
                assert item.description, f"{group}.{prop.identifier}: {item.identifier}"


def test_preset_items_are_cached_with_descriptions(registered) -> None:
    items = compare_props._preset_items(None, None)
    assert items is compare_props._preset_items(None, None)  # one list, kept alive for Blender
    presets = available_presets()
    assert [i[0] for i in items][0] == DEFAULT_PRESET
    assert sorted(i[0] for i in items) == sorted(presets)
    for identifier, _name, description, _number in items:
        assert presets[identifier].description in description


@pytest.mark.parametrize(("setup", "message"), [
    ("no_method", "No method ticked"),
    ("letters", "bad resolution 'abc'"),
    ("too_big", "must lie in"),
    ("empty", "no resolutions"),
])
def test_invalid_input_cancels_and_keeps_results(registered, setup: str, message: str) -> None:
    settings = registered
    kept = settings.results.add()
    kept.method, kept.error_pct = "kept", 1.5
    if setup == "no_method":
        _untick_all(settings)
    else:
        settings.resolutions = {"letters": "512,abc", "too_big": "512,1000000", "empty": " , "}[setup]
    status = settings.status
    for call in (compare_ops.OMNIWARP_OT_compare.execute, compare_ops.OMNIWARP_OT_compare.invoke):
        reports = Reports()
        fake = SimpleNamespace(report=reports, _timer=None)
        args = (fake, bpy.context) if call.__name__ == "execute" else (fake, bpy.context, None)
        assert call(*args) == {"CANCELLED"}
        assert len(reports.errors()) == 1 and message in reports.errors()[0], reports.items
        assert not compare_job.is_running()
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.omniwarp.compare("EXEC_DEFAULT")
    assert [r.method for r in settings.results] == ["kept"] and settings.results[0].error_pct == 1.5
    assert settings.status == status


def test_build_preset_makes_a_new_scene(registered) -> None:
    from addon.reference.blender_scene import remove_blender_scene

    window = bpy.context.window
    original = bpy.context.scene
    objects = {o.name: tuple(o.matrix_world.translation) for o in original.objects}
    scenes = set(bpy.data.scenes.keys())
    registered.camera_size = (64, 48)
    registered.resolutions = "256"
    assert bpy.ops.omniwarp.build_preset() == {"FINISHED"}
    (name,) = set(bpy.data.scenes.keys()) - scenes
    scene = bpy.data.scenes[name]
    try:
        assert window is not None and window.scene == scene and scene != original
        assert DEFAULT_PRESET in name
        assert (scene.render.resolution_x, scene.render.resolution_y) == (64, 48)
        assert any(o.type == "LIGHT" for o in scene.objects) and scene.camera is not None
        assert scene.omniwarp_compare.resolutions == "256"  # the tool's settings came along
        assert {o.name: tuple(o.matrix_world.translation) for o in original.objects} == objects
    finally:
        window.scene = original
        remove_blender_scene(scene)


def test_export_refuses_bad_requests(registered, tmp_path: Path) -> None:
    op = compare_ops.OMNIWARP_OT_export_results
    settings = registered
    reports = Reports()
    settings.export_path = str(tmp_path / "out.json")
    assert op.execute(SimpleNamespace(report=reports), bpy.context) == {"CANCELLED"}
    assert "Nothing to export" in reports.errors()[0]
    row = settings.results.add()
    row.method, row.resolution, row.total_ms, row.error_pct = "cube", 512, 12.5, 0.25
    for path, message in (("//out.json", "not saved"), (str(tmp_path / "out.txt"), ".json or .csv"), ("", "Set")):
        reports = Reports()
        settings.export_path = path
        assert op.execute(SimpleNamespace(report=reports), bpy.context) == {"CANCELLED"}
        assert message in reports.errors()[0], reports.items
    assert not (tmp_path / "out.txt").exists()
    # Rows stored in the scene (no measurement in this session) export too.
    settings.export_path = str(tmp_path / "sub" / "out.csv")
    reports = Reports()
    assert op.execute(SimpleNamespace(report=reports), bpy.context) == {"FINISHED"}
    assert str(tmp_path / "sub" / "out.csv") in reports.items[0][1]
    (line,) = list(csv.DictReader((tmp_path / "sub" / "out.csv").open(newline="")))
    assert line["method"] == "cube" and float(line["time_ms.total"]) == 12.5


class RecordingLayout:
    """Records what a panel draws; every prop() must name a real RNA property."""

    def __init__(self, record: list[tuple] | None = None) -> None:
        self.record: list[tuple] = [] if record is None else record
        self.use_property_split = False
        self.use_property_decorate = True
        self.active = self.enabled = True
        self.alignment = "EXPAND"
        self.scale_y = 1.0

    def prop(self, data, attr: str, **kwargs) -> None:
        assert attr in data.bl_rna.properties, f"{type(data).__name__} has no property {attr!r}"
        self.record.append(("prop", attr))

    def operator(self, idname: str, **kwargs) -> None:
        self.record.append(("operator", idname))

    def label(self, text: str = "", **kwargs) -> None:
        self.record.append(("label", text))
        if kwargs.get("icon", "NONE") != "NONE":
            self.record.append(("icon", kwargs["icon"]))

    def template_list(self, listtype: str, list_id: str, data, propname: str, active_data, active_prop: str,
                      **kwargs) -> None:
        assert propname in data.bl_rna.properties and active_prop in active_data.bl_rna.properties
        self.record.append(("template_list", listtype))

    def template_icon(self, icon_value: int, scale: float = 1.0) -> None:
        self.record.append(("template_icon", icon_value))

    def progress(self, **kwargs) -> None:
        self.record.append(("progress",))

    def separator(self, **kwargs) -> None:
        self.record.append(("separator",))

    def _child(self, *args, **kwargs) -> RecordingLayout:
        return RecordingLayout(self.record)

    row = column = box = grid_flow = _child

    def of(self, kind: str) -> list:
        return [r[1] for r in self.record if r[0] == kind]


def _draw(settings, source: str) -> RecordingLayout:
    settings.source = source
    layout = RecordingLayout()
    context = SimpleNamespace(scene=bpy.context.scene, region=SimpleNamespace(width=300), active_object=None)
    compare_ui.OMNIWARP_PT_compare.draw(SimpleNamespace(layout=layout), context)
    return layout


def test_panel_draws_every_control(registered) -> None:
    settings = registered
    image = bpy.data.images.new("omniwarp_test_plot", 8, 8)
    try:
        settings.plot_image = image
        layout = _draw(settings, "PRESET")
        props = layout.of("prop")
        assert props[:3] == ["source", "preset", "camera_size"]
        assert {compare_props.method_prop(m) for m in method_registry.pipeline_methods()} <= set(props)
        assert {"resolutions", "frames", "cull", "export_path"} <= set(props)
        assert layout.of("operator") == ["omniwarp.build_preset", "omniwarp.compare", "omniwarp.export_results"]
        assert layout.of("template_list") == ["OMNIWARP_UL_results"]
        assert len(layout.of("template_icon")) == 1  # the plot; no mismatch image yet
        assert any(available_presets()[DEFAULT_PRESET].description[:15] in text for text in layout.of("label"))
        current = _draw(settings, "CURRENT")
        assert "preset" not in current.of("prop") and "omniwarp.build_preset" not in current.of("operator")
        assert any("Camera:" in text for text in current.of("label"))
    finally:
        settings.plot_image = None
        bpy.data.images.remove(image)


def test_results_list_draws_a_row(registered) -> None:
    settings = registered
    item = settings.results.add()
    item.method, item.resolution, item.error_pct, item.total_ms, item.passes = "cube+notw", 1024, 0.125, 33.3, 5
    layout = RecordingLayout()
    compare_ui.OMNIWARP_UL_results.draw_item(SimpleNamespace(layout_type="DEFAULT"), bpy.context, layout, settings,
                                             item, 0, settings, "active_result", 0)
    assert layout.of("label") == ["cube+notw", "1024", "0.125 %", "33.3 ms", "5 p"]


def test_the_selected_rows_note_is_drawn_and_kept(registered) -> None:
    """A row's note (what no method draws, readers/left_out.py) shows under the selected
    row, flagged in the list, and survives the stored copy the export reads."""
    settings = registered
    settings.results.clear()
    item = settings.results.add()
    item.method, item.resolution, item.preset = "dpsm", 1024, "groom"
    item.note = "hair curves that Cycles shadows with, not drawn by OmniWarp's methods: Strands; true displacement"
    settings.active_result = 0
    try:
        layout = _draw(settings, "CURRENT")
        labels = layout.of("label")
        assert any(text.startswith("hair curves that Cycles") for text in labels), labels
        assert "true displacement" in labels and layout.of("icon").count("ERROR") == 2
        row = RecordingLayout()
        compare_ui.OMNIWARP_UL_results.draw_item(SimpleNamespace(layout_type="DEFAULT"), bpy.context, row,
                                                 settings, item, 0, settings, "active_result", 0)
        assert row.of("icon") == ["ERROR"]
        assert compare_job.stored_row(item)["note"] == item.note
    finally:
        settings.results.clear()


def test_unfit_methods_are_dropped_after_the_reference(registered) -> None:
    """Like `compare`, the panel skips ticked methods the reference's light does not take,
    and stops with a named error when none is left."""
    from addon.core.errors import InputError

    job = SimpleNamespace(reference=SimpleNamespace(emission="sun"), preset="sun_field",
                          tasks=[("dpsm", 512), ("psm", 512), ("unfold", 1024), ("sm", 1024)])
    note = compare_job._drop_unfit_tasks(job)
    assert job.tasks == [("psm", 512), ("sm", 1024)]
    assert "dpsm" in note and "unfold" in note
    job = SimpleNamespace(reference=SimpleNamespace(emission="omni"), preset="room_omni", tasks=[("psm", 512)])
    with pytest.raises(InputError, match="none of the ticked methods fits the omni light"):
        compare_job._drop_unfit_tasks(job)


# ----------------------------------------------------------------------------
# the background job's protocol (compare_background.py), with a stand-in child
# ----------------------------------------------------------------------------
def _row(method: str, resolution: int, error: float) -> dict:
    return {"preset": "room_omni", "method": method, "resolution": resolution, "error_pct": error,
            "false_shadow_pct": error / 2, "false_lit_pct": error / 2, "passes": 2, "cull": True,
            "time_ms": {"total": 3.0, "analysis": 1.0, "shadow_maps": 1.0, "shadow_test": 1.0}}


def _background_job(registered, tmp_path: Path, script: str):
    """A job whose child is `python -c script` (it writes the events a real child would)."""
    import subprocess
    import sys

    from addon.blender import compare_background

    registered.source = "PRESET"
    registered.preset = "room_omni"
    _untick_all(registered)
    registered.use_dpsm = registered.use_cube = True
    registered.resolutions = "256"
    job = compare_job.start_job(bpy.context, Reports())
    job.out_dir = tmp_path
    (tmp_path / "tmp").mkdir()
    job.child = compare_background.ChildRun(proc=subprocess.Popen([sys.executable, "-c", script]), out_dir=tmp_path)
    return job


def test_the_job_reads_whole_lines_and_shows_rows_as_they_come(registered, tmp_path: Path) -> None:
    """Events are taken line by line as the child appends them (a half-written line waits);
    each row goes into the results list at once; the end event ends the job."""
    from addon.blender import compare_background

    job = _background_job(registered, tmp_path, "import time; time.sleep(30)")
    events = tmp_path / compare_background.EVENTS_FILE
    try:
        reference = json.dumps({"event": "reference", "tasks": [["dpsm", 256], ["cube", 256]], "note": ""})
        first = json.dumps({"event": "row", "row": _row("dpsm", 256, 0.5), "seconds": 1.5})
        events.write_text(reference + "\n" + first[:20])
        assert compare_ops._read_child(job) is None
        assert job.reference is not None and job.next_task == 0 and len(registered.results) == 0
        with events.open("a") as stream:
            stream.write(first[20:] + "\n")
        assert compare_ops._read_child(job) is None
        assert [(item.method, item.resolution, item.error_pct) for item in registered.results] == [("dpsm", 256, 0.5)]
        assert registered.progress == pytest.approx(2 / 3) and "row 2/2 cube @ 256" in registered.status
        second = json.dumps({"event": "row", "row": _row("cube", 256, 0.25), "seconds": 1.0})
        with events.open("a") as stream:
            stream.write(second + "\n" + json.dumps({"event": "done", "plot": False, "warnings": []}) + "\n")
        end = compare_ops._read_child(job)
        assert end == {"event": "done", "plot": False, "warnings": []} and job.finished
        assert [item.method for item in registered.results] == ["dpsm", "cube"]
        assert compare_job.rows_for_export(bpy.context.scene)[1]["error_pct"] == 0.25
    finally:
        job.child.kill_now()
    assert not (tmp_path / "tmp").exists()  # the child's temporary folder goes with it


def test_a_child_that_ends_without_a_result_says_why(registered, tmp_path: Path) -> None:
    """A child that dies (a crash, a missing extension) fails the job with its last line."""
    job = _background_job(registered, tmp_path, "import sys; print('boom: no module omniwarp'); sys.exit(3)")
    from addon.blender import compare_background

    (tmp_path / compare_background.LOG_FILE).write_text("Blender 5.2\nboom: no module omniwarp\n")
    job.child.proc.wait()
    assert compare_ops._read_child(job) is None and job.child.exited()
    message = compare_ops._child_ended(job.child)
    assert "exit 3" in message and "boom: no module omniwarp" in message and "child.log" in message
    job.child.kill_now()


def test_the_spec_rebuilds_the_job(registered, tmp_path: Path) -> None:
    """What the child rebuilds from job.json is the job the panel set up."""
    from addon.blender import compare_background, compare_child

    registered.source = "PRESET"
    registered.preset = "room_omni"
    _untick_all(registered)
    registered.use_dpsm = registered.use_exact = True
    registered.resolutions = "256,1024"
    job = compare_job.start_job(bpy.context, Reports())
    spec = json.loads(json.dumps(compare_background.job_spec(job)))
    rebuilt = compare_child.job_from_spec(spec)
    for name in ("source", "preset", "camera_size", "light_name", "hard", "tasks", "out_dir"):
        assert getattr(rebuilt, name) == getattr(job, name), name
    assert (rebuilt.options.methods, rebuilt.options.resolutions, rebuilt.options.cull, rebuilt.options.frames) == \
        (job.options.methods, job.options.resolutions, job.options.cull, job.options.frames)
