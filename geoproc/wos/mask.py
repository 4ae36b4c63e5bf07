"""Domains from binary mask images, traced into polylines.

The mask is read through OpenImageIO (any format it reads); foreground is
``value > 0.5`` of the first channel that is not alpha (normalized to [0, 1],
alpha associated; see :func:`read_mask`). Foreground pixels that touch
only at a corner are separate regions (4-connected foreground, 8-connected
background). Its outline is the
0.5 iso-contour of the padded mask (contourpy's marching squares), so a traced
region's area matches its pixel count. Coordinates are pixel units with the
origin at the image's bottom-left corner and y pointing up: pixel ``(row, col)``
covers ``[col, col+1] x [H-row-1, H-row]``.
"""

from __future__ import annotations

import os

import contourpy
import numpy as np

from geoproc.c_output import c_stderr_silenced
from geoproc.errors import InputError
from geoproc.wos.domain import Domain, build_domain


class NoImageReader(InputError):
    """The file is in no format OpenImageIO has a reader for."""


def read_mask(path: str) -> np.ndarray:
    """Read an image through OpenImageIO; return (H, W) bool foreground over
    its display window (see :func:`read_mask_window`)."""
    window, (row0, col0), (H, W) = read_mask_window(path)
    mask = np.zeros((H, W), bool)
    mask[row0:row0 + window.shape[0], col0:col0 + window.shape[1]] = window
    return mask


def read_mask_window(path: str) -> tuple[np.ndarray, tuple[int, int], tuple[int, int]]:
    """Read an image through OpenImageIO: the foreground of the part of its
    display window that holds pixels, where it lies, and the display size.

    The mask channel is the first that is not alpha (an OpenEXR file lists its
    channels by name, so a grey image with alpha read A before Y), with alpha
    associated as OpenImageIO reads it (a PNG's values multiplied by its
    alpha, an OpenEXR's as stored, already so): transparent pixels are
    background, so a white cut-out on a transparent background is its shape.
    The pixels cover the whole image (an OpenEXR data window smaller than the
    display window is placed in it, the rest background), and an orientation
    tag (TIFF, JPEG) is applied, so the mask is traced as displayed. Only the
    data window's pixels are read: a small file may declare a display window
    of billions of pixels.

    Returns
    -------
    window : (h, w) bool
        Foreground (``value > 0.5``) of the data window clipped to the display
        window; (0, 0) when they do not meet.
    (row0, col0) : int
        Its first row (from the top) and column in the display window.
    (H, W) : int
        The display window's height and width, in pixels.
    """
    import OpenImageIO as oiio

    with c_stderr_silenced():
        buf = oiio.ImageBuf(path)
        opened = not buf.has_error
        read = _mask_channel(oiio, buf) if opened else None
    if not opened:
        message = buf.geterror().strip().splitlines()[0].removeprefix("Could not open file: ")
        if "could not find a format reader" in message:  # its message repeats the path; say what is read
            ext = os.path.splitext(path)[1]
            raise NoImageReader(path, f"not an image OpenImageIO can read "
                                      f"(no reader for {repr(ext) + ' files' if ext else 'a file without extension'})")
        raise InputError(path, f"cannot read image: {message}")
    pixels, corner, size = read if read is not None else (None, (0, 0), (0, 0))
    if buf.has_error or pixels is None or min(size) <= 0:
        # fetch the error: a buffer destroyed with one pending prints it on standard output
        pending = buf.geterror().strip().splitlines() if buf.has_error else []
        raise InputError(path, "cannot read image pixels" + (f": {pending[0]}" if pending else ""))
    pixels = np.asarray(pixels)
    if pixels.ndim == 4:  # volume images: first slice
        pixels = pixels[0]
    chan = pixels[..., 0] if pixels.ndim == 3 else pixels
    return np.nan_to_num(chan) > 0.5, corner, size


def _mask_channel(oiio, buf):
    """The pixels (h, w, 1) float32 of ``buf``'s first channel that is not
    alpha, over its data window clipped to its display window and as
    displayed, with the window's (row, column) in the display window and the
    display window's (height, width) (see :func:`read_mask_window`); None when
    the buffer cannot be read."""
    if buf.orientation != 1:
        buf = oiio.ImageBufAlgo.reorient(buf)
    spec = buf.spec()
    channel = next((c for c in range(spec.nchannels) if c != spec.alpha_channel), 0)
    x0, y0 = max(spec.x, spec.full_x), max(spec.y, spec.full_y)
    x1 = min(spec.x + spec.width, spec.full_x + spec.full_width)
    y1 = min(spec.y + spec.height, spec.full_y + spec.full_height)
    size = (spec.full_height, spec.full_width)
    if x1 <= x0 or y1 <= y0:  # no pixel inside the display window: all background
        return np.zeros((0, 0), np.float32), (0, 0), size
    roi = oiio.ROI(x0, x1, y0, y1, spec.z, spec.z + max(spec.depth, 1), channel, channel + 1)
    return buf.get_pixels(oiio.FLOAT, roi), (y0 - spec.full_y, x0 - spec.full_x), size


def trace_mask(mask: np.ndarray) -> list[np.ndarray]:
    """Trace a boolean mask (H, W) into closed loops (pixel units, y up).

    Returns
    -------
    list of (n_i, 2) float64
        Closed loops (first vertex not repeated), unoriented.
    """
    H, W = mask.shape
    z = np.zeros((H + 2, W + 2))
    z[1:-1, 1:-1] = mask[::-1].astype(np.float64)  # row 0 at the bottom (y up)
    xs = np.arange(W + 2) - 0.5  # padded column c has its center at x = c - 1 + 0.5
    ys = np.arange(H + 2) - 0.5
    gen = contourpy.contour_generator(xs, ys, z, line_type=contourpy.LineType.Separate)
    loops = []
    for line in gen.lines(0.5):
        L = np.asarray(line, dtype=np.float64)
        if len(L) > 1 and np.allclose(L[0], L[-1]):
            L = L[:-1]
        if len(L) >= 3:
            loops.append(L)
    return loops


def load_domain_mask(path: str) -> Domain:
    """Read a mask image and trace it into a :class:`Domain` (raises InputError)."""
    window, (row0, col0), (H, W) = read_mask_window(path)
    if not window.any():
        raise InputError(path, "mask has no foreground pixels (value > 0.5 in the first channel that is not "
                               "alpha, times alpha): a dark shape on a light or transparent background reads as "
                               "background; invert the image")
    # traced in the window, then placed: the display window's bottom row is y = 0
    shift = np.array([col0, H - row0 - window.shape[0]], dtype=np.float64)
    loops = [L + shift for L in trace_mask(window)]
    dom = build_domain(loops, source=path)
    dom.traced = True
    return dom
