"""The panel (render properties), its settings, the preferences, the Bake
operator (modal with a progress bar and Esc; EXEC runs the same bake
synchronously) and the automatic re-bake."""

import json

import bpy
from bpy.props import BoolProperty, EnumProperty, FloatProperty, IntProperty, PointerProperty, StringProperty

from . import job as jobs

ADDON = __package__

_current = None  # the Job in flight, one at a time

_MAPS = [
    ("normal", "Normal", "tangent-space normal map"),
    ("height", "Height", "distance from the low surface to the high"),
    ("ao", "AO", "ambient occlusion of the high"),
    ("bent-normal", "Bent normal", "average unoccluded direction"),
    ("curvature", "Curvature", "mean curvature of the high"),
    ("thickness", "Thickness", "how thick the high is under the surface"),
    ("object-normal", "Object normal", "object-space normal map"),
]
_PRESETS = [
    ("BLENDER", "Blender", "green up, B per pixel (Blender's Normal Map node)"),
    ("NONE", "None", "nmbake's defaults"),
    ("UNITY", "Unity", ""),
    ("UNREAL", "Unreal", "green down"),
    ("GODOT", "Godot", ""),
    ("GLTF", "glTF", ""),
    ("MAYA", "Maya", ""),
    ("3DSMAX", "3ds Max", "green down"),
    ("SUBSTANCE", "Substance", ""),
]


def _is_mesh(_self, obj):
    return obj.type == "MESH"


class NMBakePreferences(bpy.types.AddonPreferences):
    bl_idname = ADDON

    nmbake_path: StringProperty(
        name="nmbake binary", subtype="FILE_PATH",
        description="The nmbake executable; empty: $NMBAKE, else nmbake on PATH")

    def draw(self, _context):
        self.layout.prop(self, "nmbake_path")


class NMBakeSettings(bpy.types.PropertyGroup):
    low_object: PointerProperty(name="Low", type=bpy.types.Object, poll=_is_mesh)
    low_collection: PointerProperty(name="Low collection", type=bpy.types.Collection,
                                    description="Its mesh objects as the low parts (overrides the object)")
    high_object: PointerProperty(name="High", type=bpy.types.Object, poll=_is_mesh)
    high_collection: PointerProperty(name="High collection", type=bpy.types.Collection,
                                     description="Its mesh objects as the high parts (overrides the object)")
    cage_object: PointerProperty(name="Cage", type=bpy.types.Object, poll=_is_mesh,
                                 description="Optional: the low's triangles, moved out")
    cage_collection: PointerProperty(name="Cage collection", type=bpy.types.Collection)
    size: EnumProperty(name="Size", default="1024", items=[
        (str(n), "%d" % n, "%d x %d texels" % (n, n)) for n in (256, 512, 1024, 2048, 4096, 8192)])
    samples: EnumProperty(name="Samples", default="4", items=[
        (str(n), str(n), "%d samples per texel" % n) for n in (1, 4, 16, 64)])
    maps: EnumProperty(name="Maps", options={"ENUM_FLAG"}, items=_MAPS, default={"normal"})
    preset: EnumProperty(name="Preset", items=_PRESETS, default="BLENDER")
    tangents: EnumProperty(name="Tangents", default="MIKKTSPACE", items=[
        ("MIKKTSPACE", "Triangles (Cycles)",
         "MikkTSpace on the triangles Blender renders (loop triangles), computed by nmbake: what Cycles "
         "decodes with, and an engine reading a triangulated export"),
        ("BLENDER", "Blender mesh (EEVEE)",
         "Blender's own tangents (calc_tangents: quads split on MikkTSpace's own diagonal), written with "
         "the low: what EEVEE and the viewport decode with"),
    ])
    uv_map: StringProperty(name="UV map", description="Empty: each low object's active render UV map")
    output_dir: StringProperty(name="Folder", subtype="DIR_PATH", default="//nmbake/")
    name_template: StringProperty(name="Name", default="<LOW>_<MAP>.png",
                                  description="Tokens: <LOW> (the low object or collection), <MAP>")
    apply_material: BoolProperty(name="Set up material", default=True,
                                 description="Wire the normal map into the low's materials (Normal Map node)")
    auto_rebake: BoolProperty(name="Re-bake on change", default=False,
                              description="Bake again when the low or cage changes (after a pause)")
    status: StringProperty(name="Status")
    misses: IntProperty(name="Misses")
    miss_rate: FloatProperty(name="Miss rate")
    seconds_total: FloatProperty(name="Total seconds")
    seconds_export: FloatProperty(name="Export seconds")
    seconds_bake: FloatProperty(name="Bake seconds")
    seconds_load: FloatProperty(name="Load seconds")
    reused_high: BoolProperty(name="High reused")
    quads: IntProperty(name="Quads and n-gons of the low")
    last_report: StringProperty(name="Report (JSON)")
    last_request: StringProperty(name="Request (JSON)")


def _binary(context):
    prefs = context.preferences.addons.get(ADDON)
    path = prefs.preferences.nmbake_path if prefs is not None else ""
    return jobs.find_nmbake(bpy.path.abspath(path) if path else None)


def _start(context, settings):
    """A started Job, or raises BakeError / nmbake's NotFound."""
    global _current
    if _current is not None and not _current.done:
        raise jobs.BakeError("a bake is running")
    job = jobs.Job(settings, _binary(context))
    settings.status = "exporting"
    job.start(context)
    settings.last_request = json.dumps(job.request_keys)
    _current = job
    return job


def _store(context, settings, job):
    """Finishes `job`: the maps into images, its figures into the panel.
    Returns an error message or None."""
    global _current
    _current = None
    if job.error is not None:
        settings.status = "cancelled" if job.cancelled else "failed: %s" % job.error
        return settings.status
    job.finish(context)
    report = job.report
    rays = report.get("rays", {})
    settings.misses = int(rays.get("misses", 0))
    settings.miss_rate = float(rays.get("miss_rate", 0.0))
    settings.seconds_export = job.timings.get("export", 0.0)
    settings.seconds_bake = job.timings.get("bake", 0.0)
    settings.seconds_load = job.timings.get("load", 0.0)
    settings.seconds_total = settings.seconds_export + settings.seconds_bake + settings.seconds_load
    reused = report.get("reused", {})
    settings.reused_high = bool(reused.get("high_mesh")) and bool(reused.get("high_scene"))
    settings.quads = job.quads
    report = dict(report, blender_timings=job.timings)
    settings.last_report = json.dumps(report)
    settings.status = "baked"
    _last_fingerprint[settings.as_pointer()] = job.low_fingerprint
    return None


_last_fingerprint = {}


def _status_text(job):
    return "nmbake: %s %d%%  (Esc to cancel)" % (job.stage, int(round(job.fraction * 100)))


def modal_step(context, job, event_type, event_value, status):
    """One event of the modal bake: Esc cancels (the session's cancel), a
    timer tick shows the progress. Returns "pass" (not ours), "running" or
    "done" (the job has answered: finish it)."""
    if event_type == "ESC" and event_value == "PRESS":
        job.cancel()
        status("nmbake: cancelling")
        return "running"
    if event_type != "TIMER":
        return "pass"
    if not job.done:
        context.window_manager.progress_update(int(job.fraction * 100))
        status(_status_text(job))
        return "running"
    return "done"


class NMBAKE_OT_bake(bpy.types.Operator):
    """Bake the maps with nmbake (Esc cancels)"""

    bl_idname = "nmbake.bake"
    bl_label = "Bake"

    _timer = None
    _job = None

    def execute(self, context):
        # Synchronous: the same bake, for scripts and for blender -b.
        settings = context.scene.nmbake
        try:
            job = _start(context, settings)
        except (jobs.BakeError, jobs.client.Error) as e:
            settings.status = "failed: %s" % e
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        job.wait()
        error = _store(context, settings, job)
        if error:
            self.report({"ERROR"}, error)
            return {"CANCELLED"}
        return {"FINISHED"}

    def invoke(self, context, _event):
        settings = context.scene.nmbake
        try:
            self._job = _start(context, settings)
        except (jobs.BakeError, jobs.client.Error) as e:
            settings.status = "failed: %s" % e
            self.report({"ERROR"}, str(e))
            return {"CANCELLED"}
        wm = context.window_manager
        wm.progress_begin(0, 100)
        self._timer = wm.event_timer_add(0.1, window=context.window)
        wm.modal_handler_add(self)
        context.workspace.status_text_set(_status_text(self._job))
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        step = modal_step(context, job, event.type, event.value, context.workspace.status_text_set)
        if step == "pass":
            return {"PASS_THROUGH"}
        if step == "running":
            return {"RUNNING_MODAL"}
        wm = context.window_manager
        wm.event_timer_remove(self._timer)
        wm.progress_end()
        context.workspace.status_text_set(None)
        error = _store(context, context.scene.nmbake, job)
        _redraw(context)
        if error:
            self.report({"WARNING"} if job.cancelled else {"ERROR"}, error)
            return {"CANCELLED"}
        return {"FINISHED"}


def _redraw(context):
    for window in context.window_manager.windows:
        for area in window.screen.areas:
            if area.type == "PROPERTIES":
                area.tag_redraw()


class NMBAKE_PT_panel(bpy.types.Panel):
    bl_label = "nmbake"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"

    def draw(self, context):
        s = context.scene.nmbake
        layout = self.layout
        layout.use_property_split = True
        for role in ("low", "high", "cage"):
            col = layout.column(align=True)
            col.prop(s, role + "_object")
            col.prop(s, role + "_collection", text="Collection")
        layout.prop(s, "size")
        layout.prop(s, "samples")
        layout.prop(s, "maps")
        layout.prop(s, "preset")
        layout.prop(s, "tangents")
        layout.prop(s, "uv_map")
        layout.prop(s, "output_dir")
        layout.prop(s, "name_template")
        layout.prop(s, "apply_material")
        layout.prop(s, "auto_rebake")
        running = _current is not None and not _current.done
        row = layout.row()
        row.enabled = not running
        row.operator(NMBAKE_OT_bake.bl_idname, icon="RENDER_STILL")
        box = layout.box()
        box.label(text="Status: %s" % (s.status or "-"))
        if s.last_report:
            box.label(text="Misses: %d (%.3f%%)" % (s.misses, s.miss_rate * 100.0))
            box.label(text="Time: %.2f s (export %.2f, bake %.2f, load %.2f)" % (
                s.seconds_total, s.seconds_export, s.seconds_bake, s.seconds_load))
            box.label(text="High reused: %s" % ("yes" if s.reused_high else "no"))
            if s.quads:
                # Measured (README "Baking from Blender"): on quads Cycles and
                # EEVEE decode with different tangents.
                box.label(text="%d quads/n-gons: Cycles and EEVEE differ there;" % s.quads, icon="ERROR")
                box.label(text="a Triangulate modifier on the low makes them agree")


# -- automatic re-bake -----------------------------------------------------

_AUTO_DELAY = 0.75


def _watched(settings):
    objects = jobs.mesh_objects(settings.low_object, settings.low_collection)
    objects += jobs.mesh_objects(settings.cage_object, settings.cage_collection)
    return objects


@bpy.app.handlers.persistent
def _on_depsgraph_update(scene, depsgraph):
    settings = scene.nmbake
    if not settings.auto_rebake:
        return
    names = {o.name for o in _watched(settings)}
    for update in depsgraph.updates:
        target = update.id.original if update.id is not None else None
        if isinstance(target, bpy.types.Object) and target.name in names and (
                update.is_updated_geometry or update.is_updated_transform):
            # Debounce: every change restarts the wait.
            if bpy.app.timers.is_registered(_auto_tick):
                bpy.app.timers.unregister(_auto_tick)
            bpy.app.timers.register(_auto_tick, first_interval=_AUTO_DELAY)
            return


def _auto_tick():
    """The debounced change: bakes when the low or cage really changed."""
    global _auto_job
    context = bpy.context
    settings = context.scene.nmbake
    if not settings.auto_rebake:
        return None
    if _current is not None and not _current.done:
        return _AUTO_DELAY  # one bake at a time: look again later
    depsgraph = context.evaluated_depsgraph_get()
    stamp = jobs.fingerprint(_watched(settings), depsgraph, settings.uv_map)
    if stamp == _last_fingerprint.get(settings.as_pointer()):
        return None  # our own material edits, or a change that changed nothing
    try:
        _auto_job = _start(context, settings)
    except (jobs.BakeError, jobs.client.Error) as e:
        settings.status = "failed: %s" % e
        return None
    context.window_manager.progress_begin(0, 100)
    bpy.app.timers.register(_auto_poll, first_interval=0.1)
    return None


_auto_job = None


def _auto_poll():
    """Follows the automatic bake; finishes it on the main thread."""
    global _auto_job
    job = _auto_job
    if job is None:
        return None
    wm = bpy.context.window_manager
    if not job.done:
        wm.progress_update(int(job.fraction * 100))
        return 0.1
    wm.progress_end()
    _auto_job = None
    _store(bpy.context, job.settings, job)
    _redraw(bpy.context)
    return None


@bpy.app.handlers.persistent
def _on_load_pre(*_args):
    """Another file: a bake of the old one is cancelled and forgotten (its
    scene's settings are gone)."""
    global _current, _auto_job
    for job in (_current, _auto_job):
        if job is not None and not job.done:
            job.cancel()
    _current = _auto_job = None
    _last_fingerprint.clear()


classes = (NMBakePreferences, NMBakeSettings, NMBAKE_OT_bake, NMBAKE_PT_panel)


def register():
    for cls in classes:
        bpy.utils.register_class(cls)
    bpy.types.Scene.nmbake = PointerProperty(type=NMBakeSettings)
    bpy.app.handlers.depsgraph_update_post.append(_on_depsgraph_update)
    bpy.app.handlers.load_pre.append(_on_load_pre)


def unregister():
    if _on_depsgraph_update in bpy.app.handlers.depsgraph_update_post:
        bpy.app.handlers.depsgraph_update_post.remove(_on_depsgraph_update)
    if _on_load_pre in bpy.app.handlers.load_pre:
        bpy.app.handlers.load_pre.remove(_on_load_pre)
    for timer in (_auto_tick, _auto_poll):
        if bpy.app.timers.is_registered(timer):
            bpy.app.timers.unregister(timer)
    if _current is not None and not _current.done:
        _current.cancel()
    jobs.close_session()
    jobs.remove_exports()
    del bpy.types.Scene.nmbake
    for cls in reversed(classes):
        bpy.utils.unregister_class(cls)


