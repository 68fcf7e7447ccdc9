"""vtkfix.py: what the VTK input tests (input-vti.sh, input-vtk.sh) write
with VTK's own writers (python3-vtk9), and the values they expect back.
Imported with tests/ on PYTHONPATH."""
import numpy as np
from vtkmodules.vtkIOXML import vtkXMLImageDataWriter


def fields(seed, n):
    """Three arrays of n points: a float32 velocity of 3 components whose
    magnitudes span 1e-3..1e3, a float64 grad of 2 components and a float32
    scalar p."""
    rng = np.random.default_rng(seed)
    scale = 10.0 ** rng.integers(-3, 4, n)[:, None]
    vel = (rng.standard_normal((n, 3)) * scale).astype(np.float32)
    grad = rng.standard_normal((n, 2))
    p = rng.standard_normal(n).astype(np.float32)
    return vel, grad, p


def lengths(arr):
    """Each point's length as tvpal reads it with --magnitude: float64
    squares summed in component order, the root rounded to float32."""
    d = arr.astype(np.float64).reshape(arr.shape[0], -1)
    s = d[:, 0] * d[:, 0]
    for c in range(1, d.shape[1]):
        s = s + d[:, c] * d[:, c]
    return np.sqrt(s).astype(np.float32)


def write_vti(im, path, mode):
    """im into path with vtkXMLImageDataWriter in data mode `mode`:
    appended (VTK's default: base64, zlib), raw (appended, unencoded,
    uncompressed), binary or ascii."""
    w = vtkXMLImageDataWriter()
    w.SetFileName(path)
    w.SetInputData(im)
    if mode == "raw":
        w.SetDataModeToAppended()
        w.EncodeAppendedDataOff()
        w.SetCompressorTypeToNone()
    elif mode == "binary":
        w.SetDataModeToBinary()
    elif mode == "ascii":
        w.SetDataModeToAscii()
    if not w.Write():
        raise SystemExit("write failed: " + path)
