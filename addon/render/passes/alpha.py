"""See-through materials on the GPU, one life cycle: the alpha maps the parts sample, and
the maps' veil (lib/veil.glsl) that the depth pass writes and the shadow test reads."""
from __future__ import annotations

from typing import Any

from ..shaders import ALPHA_SAMPLERS, VEIL_IMAGES


class AlphaStore:
    """Alpha maps by digest (channel image and transfer table, R32F), shared by every part
    that uses the same map (thousands of instances of one leaf card upload it once)."""

    def __init__(self) -> None:
        self.textures: dict[str, tuple[Any, Any]] = {}  # digest -> (channel image, transfer table)
        self._users: dict[str, str] = {}  # part key -> digest
        self._counts: dict[str, int] = {}  # digest -> parts using it

    def hold(self, device, key: str, amap) -> int:
        """Record which alpha map a part uses (None: none), uploading the map the first time
        and freeing the one it used before with its last user; returns the bytes uploaded."""
        previous = self._users.pop(key, None)
        uploaded = 0
        if amap is not None:
            if amap.digest not in self.textures:
                image, transfer = amap.image, amap.transfer_table()
                self.textures[amap.digest] = (_channel(device, image), _channel(device, transfer[None, :]))
                uploaded = int(image.nbytes + transfer.nbytes)
            self._users[key] = amap.digest
            self._counts[amap.digest] = self._counts.get(amap.digest, 0) + 1
        if previous is not None:
            self._counts[previous] -= 1
            if not self._counts[previous]:
                del self._counts[previous]
                device.free(*self.textures.pop(previous))
        return uploaded

    def see_through(self, key: str) -> bool:
        """Whether a part samples an alpha map."""
        return key in self._users

    def textures_of(self, key: str) -> dict[str, Any]:
        """The alpha map a see-through part's programs sample (ALPHA_SAMPLERS); empty when opaque."""
        digest = self._users.get(key)
        return {} if digest is None else dict(zip(ALPHA_SAMPLERS, self.textures[digest]))

    def release(self, device) -> None:
        """Free every alpha texture (the backend's release)."""
        for textures in self.textures.values():
            device.free(*textures)
        self.textures.clear()
        self._users.clear()
        self._counts.clear()


def _channel(device, data) -> Any:
    """A one-channel float texture (R32F) of `data` (rows, columns), row 0 first."""
    rows, columns = data.shape
    return device.texture((columns, rows), "R32F", data)


class AtlasWords:
    """R32UI images of the atlas's size, by name (`images`: (type, name) pairs, as
    shaders.VEIL_IMAGES): made at the first draw that writes them, cleared once per atlas
    (`live` from that clear until the next begin_atlas). The veil is one (see-through
    parts), the haze another (passes/media.py, media)."""

    def __init__(self, images: tuple[tuple[str, str], ...]) -> None:
        self.names = tuple(name for _, name in images)
        self.images: tuple[Any, ...] | None = None
        self.size: tuple[int, int] | None = None
        self.live = False

    def ready(self, device, size: tuple[int, int]) -> dict[str, Any]:
        """The images by name, made for `size` and cleared at the first draw into this atlas."""
        if self.images is None or self.size != size:
            self.release(device)
            self.images = tuple(device.texture(size, "R32UI") for _ in self.names)
            self.size = size
        if not self.live:
            for image in self.images:
                device.clear_image(image)
            self.live = True
        return self.by_name()

    def by_name(self) -> dict[str, Any]:
        return dict(zip(self.names, self.images))

    def release(self, device) -> None:
        """Free the images (a new atlas size, or the backend's release)."""
        device.free(*(self.images or ()))
        self.images = self.size = None
        self.live = False


def Veil() -> AtlasWords:  # noqa: N802 - the veil's words, named as the backend holds them
    """The maps' veil (lib/veil.glsl): see-through crossings per atlas texel."""
    return AtlasWords(VEIL_IMAGES)
