"""Image outputs: one-channel float EXR (OpenImageIO) and colormapped PNG (matplotlib Agg)."""

from __future__ import annotations

import io
import os
import tempfile

import numpy as np

from geoproc.errors import UsageError

EXR_MAX = float(np.finfo(np.float32).max)
"""The largest magnitude a float32 EXR pixel holds (3.4e38)."""


def float32_steps(lo: float, hi: float) -> float:
    """How many float32 steps (units in the last place at the larger of |lo|
    and |hi|) the values from ``lo`` to ``hi`` span: the levels a float EXR can
    show of them. 0 when they are equal."""
    big = np.float32(max(abs(lo), abs(hi)))
    return (hi - lo) / float(np.spacing(big)) if big > 0 else 0.0


def exr_bytes(U: np.ndarray, solution: bool = True, attributes: dict[str, float] | None = None) -> bytes:
    """Encode a (H, W) float array as a one-channel float32 OpenEXR file (NaN kept).

    Row 0 is the top of the image. A ``solution`` beyond float32's range, or
    one that float32 writes as 0 everywhere, is a UsageError; other arrays
    (standard errors) are written as float32 rounds them. ``attributes``
    (name to number) go into the header as strings of the number's every
    digit (the EXR writer keeps no double attribute, and a float one rounds
    a position 1e12 away to 6e4).
    """
    import OpenImageIO as oiio

    big = float(np.abs(U[np.isfinite(U)]).max(initial=0.0)) if solution else 0.0
    if big > EXR_MAX:
        raise UsageError(f"the solution reaches {big:.3g}, beyond the float32 range of EXR "
                         f"({EXR_MAX:.3g}); rescale the boundary data")
    if big > 0 and np.float32(big) == 0:  # every pixel would read 0
        raise UsageError(f"the solution is at most {big:.3g} in magnitude, below the float32 range of EXR "
                         "(which writes it as 0); rescale the boundary data")
    U = np.ascontiguousarray(U, dtype=np.float32)
    H, W = U.shape
    spec = oiio.ImageSpec(W, H, 1, oiio.FLOAT)
    spec.channelnames = ("Y",)
    spec.attribute("compression", "zip")
    spec.attribute("DateTime", "")  # no capture date: same data, same bytes
    for name, value in (attributes or {}).items():
        spec.attribute(name, repr(float(value)))
    fd, tmp = tempfile.mkstemp(suffix=".exr")
    os.close(fd)
    try:
        out = oiio.ImageOutput.create(tmp)
        if out is None or not out.open(tmp, spec):
            raise RuntimeError(f"OpenImageIO cannot write EXR: {oiio.geterror()}")
        ok = out.write_image(U[:, :, None])
        out.close()
        if not ok:
            raise RuntimeError(f"OpenImageIO failed writing EXR: {out.geterror()}")
        with open(tmp, "rb") as fh:
            return fh.read()
    finally:
        os.unlink(tmp)


def exr_attributes(path: str) -> dict[str, float]:
    """The ``geoproc:`` header attributes of an EXR written by :func:`exr_bytes`, as numbers."""
    import OpenImageIO as oiio

    inp = oiio.ImageInput.open(path)
    try:
        spec = inp.spec()
        return {a.name: float(a.value) for a in spec.extra_attribs if a.name.startswith("geoproc:")}
    finally:
        inp.close()


def read_exr(path: str) -> np.ndarray:
    """Read a one-channel EXR written by :func:`exr_bytes` back to (H, W) float32."""
    import OpenImageIO as oiio

    buf = oiio.ImageBuf(path)
    px = np.asarray(buf.get_pixels(oiio.FLOAT))
    return px[..., 0] if px.ndim == 3 else px


MAX_HEIGHT_INCHES = 12.0
"""Height cap of the pictures (100 pixels an inch; they are 6 inches wide)."""


def png_bytes(U: np.ndarray, extent: tuple[float, float, float, float], title: str,
              cmap: str = "viridis", contours: int = 12, label: str = "u") -> bytes:
    """Colormapped PNG of a (H, W) field with contour lines; NaN pixels transparent.

    Parameters
    ----------
    U : (H, W) float
        Row 0 at the top.
    extent : (xmin, xmax, ymin, ymax)
        Domain coordinates of the image edges.
    title : str
    cmap : str
        Matplotlib colormap name.
    contours : int
        Number of contour levels (0: none).
    label : str
        Colorbar label.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    H, W = U.shape
    aspect = H / W
    # at most 12 inches tall, as it is at most 6 wide: a domain 300 times taller than wide
    # made a 600 x 128,000 pixel picture (2 GB of memory)
    fig = Figure(figsize=(6.0, min(MAX_HEIGHT_INCHES, max(2.5, 5.0 * aspect))), dpi=100)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot(1, 1, 1)
    im = ax.imshow(np.ma.masked_invalid(U), cmap=cmap, extent=extent, origin="upper",
                   interpolation="nearest")
    finite = np.isfinite(U)
    if contours and finite.sum() > 4 and np.nanmax(U) > np.nanmin(U) and min(H, W) > 2:
        xs = np.linspace(extent[0], extent[1], W + 1)
        ys = np.linspace(extent[3], extent[2], H + 1)
        xc, yc = (xs[:-1] + xs[1:]) / 2, (ys[:-1] + ys[1:]) / 2
        ax.contour(xc, yc, np.ma.masked_invalid(U), levels=contours, colors="k", linewidths=0.5)
    fig.colorbar(im, ax=ax, label=label)
    ax.set_title(title, fontsize=9, parse_math=False)  # a file name may hold '$'
    ax.set_aspect("equal")
    bio = io.BytesIO()
    fig.savefig(bio, format="png", metadata={"Software": None})
    return bio.getvalue()
