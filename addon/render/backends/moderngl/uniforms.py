"""moderngl's uniforms: a program's std140 block (shaders/uniform_block.py) in a uniform
buffer of its own, written only when a draw changes its bytes (moderngl_backend.py keeps
one a program)."""
from __future__ import annotations

from typing import Any, Mapping

from ...device import Program
from ...shaders.uniform_block import BlockState, UniformBlock

# The binding point every program's block is declared at (moderngl_glsl.py) and bound to.
BLOCK_BINDING = 0
# moderngl's `extra` slot of a uniform block's buffer: what tests/support/traffic.py counts
# as uniform bytes rather than an upload.
UNIFORM_BUFFER_TAG = "omniwarp-uniform-block"


class ProgramBlock:
    """A program's uniform block: its current values and the buffer that holds them.

    A value keeps its place in the block between draws, as a GL program's uniforms do, so a
    steady frame's draws that repeat their values write nothing."""

    def __init__(self, ctx: Any, iface: Program) -> None:
        self.state = BlockState(UniformBlock.of(iface))
        self.buffer = ctx.buffer(reserve=self.state.block.size) if iface.uniforms else None
        if self.buffer is not None:
            self.buffer.extra = UNIFORM_BUFFER_TAG

    def use(self, values: Mapping[str, Any]) -> None:
        """Write `values` over the block, send the bytes that changed, bind it for the next draw."""
        if self.buffer is None:
            return
        self.state.update(values)
        changed = self.state.take_changed()
        if changed is not None:
            offset, data = changed
            self.buffer.write(data, offset=offset)
        self.buffer.bind_to_uniform_block(BLOCK_BINDING)

    def release(self) -> None:
        if self.buffer is not None:
            self.buffer.release()
            self.buffer = None
