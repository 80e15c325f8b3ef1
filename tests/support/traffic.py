"""Counts a frame's traffic between host and GPU at moderngl's API (issue 41's figures),
or, for any backend (Blender's `gpu` among them), at the `render.device.Device` calls.

`Traffic.counting()` wraps, for the calls inside it, moderngl's:
- waits: the device's `finish`, and every read (a read waits for the GPU);
- reads: `Texture.read`, `Texture.read_into`, `Framebuffer.read`, `Buffer.read` (bytes);
- uploads: `Texture.write`, `Buffer.write`, and data given to `Context.texture` and
  `Context.buffer` (bytes);
- uniforms: bytes written to uniforms (`Uniform.value`, `Uniform.write`) and to a program's
  uniform block (a `Buffer.write` on a buffer tagged UNIFORM_BUFFER_TAG), counted apart.
"""
from __future__ import annotations

import contextlib
from dataclasses import dataclass, field
from typing import Iterator

from addon.render.backends.moderngl.uniforms import UNIFORM_BUFFER_TAG


def _size(data) -> int:
    if data is None:
        return 0
    if isinstance(data, (bytes, bytearray)):
        return len(data)
    return memoryview(data).nbytes


@dataclass
class Traffic:
    """What crossed between host and GPU while counting."""

    finishes: int = 0
    reads: int = 0
    read_bytes: int = 0
    uploads: int = 0
    upload_bytes: int = 0
    uniform_bytes: int = 0
    calls: list[str] = field(default_factory=list)  # every wait and transfer, in order

    @property
    def waits(self) -> int:
        """Host waits: finishes and reads."""
        return self.finishes + self.reads

    def row(self) -> dict[str, int]:
        return {"waits": self.waits, "finishes": self.finishes, "reads": self.reads,
                "read_bytes": self.read_bytes, "uploads": self.uploads, "upload_bytes": self.upload_bytes,
                "uniform_bytes": self.uniform_bytes}

    @contextlib.contextmanager
    def counting(self) -> Iterator["Traffic"]:
        import moderngl

        patches: list[tuple[type, str, object]] = []

        def wrap(cls: type, name: str, count) -> None:
            original = cls.__dict__[name]
            patches.append((cls, name, original))

            def wrapper(*args, **kwargs):
                result = original(*args, **kwargs)
                count(args, kwargs, result)
                return result

            setattr(cls, name, wrapper)

        def read(label):
            def count(args, kwargs, result):
                self.reads += 1
                nbytes = _size(result) if result is not None else _size(args[1] if len(args) > 1 else None)
                self.read_bytes += nbytes
                self.calls.append(f"{label} {nbytes}")
            return count

        def upload(label, position, key):
            def count(args, kwargs, result):
                data = kwargs.get(key, args[position] if len(args) > position else None)
                if data is None:
                    return
                if getattr(args[0], "extra", None) == UNIFORM_BUFFER_TAG:
                    self.uniform_bytes += _size(data)  # a program's uniform block, not an upload
                    return
                self.uploads += 1
                self.upload_bytes += _size(data)
                self.calls.append(f"{label} {_size(data)}")
            return count

        def finish(args, kwargs, result):
            self.finishes += 1
            self.calls.append("finish")

        # The device's finish (a glFinish through ctypes, without the GIL: moderngl's own
        # Context.finish only where EGL cannot give it, inside this call).
        from addon.render.backends.moderngl.backend import ModernGLDevice

        wrap(ModernGLDevice, "finish", finish)
        wrap(moderngl.Texture, "read", read("Texture.read"))
        wrap(moderngl.Texture, "read_into", read("Texture.read_into"))
        wrap(moderngl.Framebuffer, "read", read("Framebuffer.read"))
        wrap(moderngl.Buffer, "read", read("Buffer.read"))
        wrap(moderngl.Texture, "write", upload("Texture.write", 1, "data"))
        wrap(moderngl.Buffer, "write", upload("Buffer.write", 1, "data"))
        wrap(moderngl.Context, "texture", upload("Context.texture", 3, "data"))
        wrap(moderngl.Context, "buffer", upload("Context.buffer", 1, "data"))

        def uniform(args, kwargs, result):
            self.uniform_bytes += _size(args[1]) if isinstance(args[1], (bytes, bytearray)) else 4

        wrap(moderngl.Uniform, "write", uniform)
        value = moderngl.Uniform.__dict__["value"]
        patches.append((moderngl.Uniform, "value", value))

        def set_value(this, new):
            self.uniform_bytes += 4 * max(1, len(new) if isinstance(new, (tuple, list)) else 1)
            value.fset(this, new)

        moderngl.Uniform.value = property(value.fget, set_value)
        try:
            yield self
        finally:
            for cls, name, original in reversed(patches):
                setattr(cls, name, original)


def _nbytes(value) -> int:
    import numpy as np

    return int(np.asarray(value).size) * 4  # a uniform is float32 or int32 a component


@contextlib.contextmanager
def counting_device(device, traffic: Traffic) -> Iterator[Traffic]:
    """Count, into `traffic`, the transfers a `Device` is asked for while inside:
    - waits: `finish`, and every `read` (a read waits for the GPU);
    - reads: the bytes read back, the whole texture's where the device reads whole ones
      (`Device.reads_whole`: Blender's `gpu` has no rectangle read);
    - uploads: `texture` with data, `upload`, and the vertex arrays of a `vertices` draw;
    - uniforms: every uniform value handed to a draw or dispatch (Blender's `gpu` sends
      them all each time).
    Calls the device makes to itself are counted once."""
    import numpy as np

    saved = {}
    depth = [0]

    def wrap(name, count):
        real = getattr(device, name)
        saved[name] = real

        def counted(*args, **kwargs):
            depth[0] += 1
            try:
                result = real(*args, **kwargs)
            finally:
                depth[0] -= 1
            if depth[0] == 0:
                count(args, kwargs, result)
            return result

        setattr(device, name, counted)

    def read(args, kwargs, result):
        traffic.reads += 1
        nbytes = int(result.nbytes)
        if device.reads_whole:
            width, height = device.texture_size(args[0])
            nbytes = int(result.nbytes) // max(1, result.shape[0] * result.shape[1]) * width * height
        traffic.read_bytes += nbytes
        traffic.calls.append(f"read {nbytes}")

    def finish(args, kwargs, result):
        traffic.finishes += 1
        traffic.calls.append("finish")

    def upload(position):
        def count(args, kwargs, result):
            data = kwargs.get("data", args[position] if len(args) > position else None)
            if data is not None:
                traffic.uploads += 1
                nbytes = int(np.asarray(data).nbytes)
                traffic.upload_bytes += nbytes
                traffic.calls.append(f"upload {nbytes}")
        return count

    def work(uniform_position, geometry_position):
        def count(args, kwargs, result):
            uniforms = args[uniform_position] if len(args) > uniform_position else kwargs.get("uniforms", {})
            traffic.uniform_bytes += sum(_nbytes(v) for v in uniforms.values())
            geometry = kwargs.get("geometry", args[geometry_position] if len(args) > geometry_position else None)
            if getattr(geometry, "kind", None) == "vertices":
                nbytes = sum(int(np.asarray(a).nbytes) for a in geometry.arrays.values())
                traffic.uploads += 1
                traffic.upload_bytes += nbytes
                traffic.calls.append(f"vertices {nbytes}")
        return count

    wrap("read", read)
    wrap("finish", finish)
    wrap("texture", upload(2))
    wrap("upload", upload(3))
    wrap("draw", work(1, 3))
    wrap("dispatch", work(1, 99))
    try:
        yield traffic
    finally:
        for name in saved:
            delattr(device, name)  # the class's methods again
