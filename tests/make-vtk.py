#!/usr/bin/env python3
"""make-vtk.py OUTDIR: writes the .pvd, .pvti and legacy .vtk fixtures of
tests/test-vtk.c and tests/input-vtk.sh into OUTDIR, from the standard
library only (the .vti pieces and steps with tests/make-vti.py's writer).

Every good file NAME.EXT has NAME.f32 beside it (a .pvd: NAME-1.f32 ..
NAME-3.f32, one per step in time order): the values a reader must give,
little-endian float32, x fastest.  bad-* are files a reader must refuse.

  series.pvd        3 .vti steps in series/ (relative paths), timesteps
                    0.5 1.0 2.5 in document order
  unsorted.pvd      the same steps listed 1.0, 2.5, 0.5 (VTK sorts them)
  pieces.pvti       5x4x3 from 2x2x1 pieces in pieces/, sharing one point
                    layer at each inner face as VTK writes them (the
                    values there equal), each piece in another encoding
  ascii-float.vtk   legacy ASCII float, SPACING 0.5 2 4, ORIGIN 1 2 3
  binary-float.vtk  legacy BINARY float (big-endian)
  binary-short.vtk  legacy BINARY short
  two-scalars.vtk   BINARY: FIELD data, SCALARS a float, VECTORS, SCALARS
                    b double, CELL_DATA SCALARS c (a: two-scalars.f32, b:
                    two-scalars-b.f32, the length of VECTORS vel:
                    two-scalars-vel.f32)

Vectors, read with --magnitude (NAME.f32: each point's length, the
squares of its components as stored summed left to right in double, the
root rounded to float32):
  vectors-ascii.vtk    ASCII VECTORS vel float only (the default array)
  scalars3.vtk         BINARY SCALARS v3 short 3
  field.vtk            BINARY POINT_DATA SCALARS a, then FIELD FieldData 2
                       (p 1 double: field-p.f32; grad 2 float:
                       field.f32), CELL_DATA FIELD with cf
  field-ascii.vtk      the same in ASCII
  vectors.pvti         5x4x3 of 2x2x1 pieces of vel Float32 3 in each
                       encoding; bad-vectors.pvti: a piece of 2
"""
import importlib.util
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location(
    'make_vti', os.path.join(HERE, 'make-vti.py'))
mv = importlib.util.module_from_spec(spec)
spec.loader.exec_module(mv)

NX, NY, NZ = mv.NX, mv.NY, mv.NZ
N = mv.N
ZLIB = 'vtkZLibDataCompressor'


def pvd(path, sets):
    """sets: (timestep, part, file) in document order."""
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="Collection" version="0.1" '
             'byte_order="LittleEndian">', '  <Collection>']
    for t, part, f in sets:
        lines.append('    <DataSet timestep="%s" group="" part="%d" '
                     'file="%s"/>' % (t, part, f))
    lines += ['  </Collection>', '</VTKFile>', '']
    with open(path, 'w') as fp:
        fp.write('\n'.join(lines))


PARRAYS = ['      <PDataArray type="Float32" Name="v"/>',
           '      <PDataArray type="Float32" Name="w"/>']


def pvti(path, pieces, origin=(1, 2, 3), spacing=(0.5, 2, 4),
         parrays=PARRAYS, active='Scalars="v"'):
    ext = (0, NX - 1, 0, NY - 1, 0, NZ - 1)
    lines = ['<?xml version="1.0"?>',
             '<VTKFile type="PImageData" version="1.0" '
             'byte_order="LittleEndian" header_type="UInt32" '
             'compressor="vtkZLibDataCompressor">',
             '  <PImageData WholeExtent="%s" GhostLevel="0" Origin="%s" '
             'Spacing="%s" Direction="1 0 0 0 1 0 0 0 1">' % (
                 ' '.join(map(str, ext)), ' '.join(map(str, origin)),
                 ' '.join(map(str, spacing))),
             '    <PPointData %s>' % active] + parrays + [
             '    </PPointData>',
             '    <PCellData>', '    </PCellData>']
    for e, src in pieces:
        lines.append('    <Piece Extent="%s" Source="%s"/>' % (
            ' '.join(map(str, e)), src))
    lines += ['  </PImageData>', '</VTKFile>', '']
    with open(path, 'w') as fp:
        fp.write('\n'.join(lines))


def sub(values, e):
    """The values of extent e of the whole 5x4x3 grid, x fastest."""
    return [values[(z * NY + y) * NX + x]
            for z in range(e[4], e[5] + 1) for y in range(e[2], e[3] + 1)
            for x in range(e[0], e[1] + 1)]


def legacy(path, arrays, binary, dims=(NX, NY, NZ), npoints=None,
           dataset='STRUCTURED_POINTS', spacing=(1, 1, 1), origin=(0, 0, 0),
           cells=(), field=False, cut=None):
    """arrays: (kind, name, vtype, values[, ncomp]), or ('FIELD', name,
    None, [(name, ncomp, vtype, values), ...]); binary values
    big-endian."""
    codes = {'float': 'f', 'double': 'd', 'short': 'h', 'unsigned_char': 'B',
             'int': 'i', 'unsigned_short': 'H', 'char': 'b'}
    out = [b'# vtk DataFile Version 3.0\n',
           b'tvpal tests/make-vtk.py fixture\n',
           b'BINARY\n' if binary else b'ASCII\n',
           ('DATASET %s\n' % dataset).encode(),
           ('DIMENSIONS %d %d %d\n' % dims).encode(),
           ('SPACING %r %r %r\n' % tuple(map(float, spacing))).encode(),
           ('ORIGIN %r %r %r\n' % tuple(map(float, origin))).encode()]

    def values(vtype, vals):
        if binary:
            return struct.pack('>%d%s' % (len(vals), codes[vtype]),
                               *vals) + b'\n'
        return (' '.join(repr(float(v)) if vtype in ('float', 'double')
                         else str(v) for v in vals) + '\n').encode()

    if field:
        out.append(b'FIELD FieldData 1\nTIME 1 1 double\n')
        out.append(values('double', [0.25]))

    def section(arrs):
        for a in arrs:
            kind, name, vtype, vals = a[:4]
            if kind == 'FIELD':
                out.append(('FIELD %s %d\n' % (name, len(vals))).encode())
                for an, nc, at, av in vals:
                    out.append(('%s %d %d %s\n' % (an, nc, len(av) // nc,
                                                   at)).encode())
                    out.append(values(at, av))
                continue
            if kind == 'SCALARS':
                out.append(('SCALARS %s %s %d\nLOOKUP_TABLE default\n' % (
                    name, vtype, a[4] if len(a) > 4 else 1)).encode())
            else:
                out.append(('%s %s %s\n' % (kind, name, vtype)).encode())
            out.append(values(vtype, vals))

    n = npoints if npoints is not None else dims[0] * dims[1] * dims[2]
    out.append(('POINT_DATA %d\n' % n).encode())
    section(arrays)
    if cells:
        out.append(('CELL_DATA %d\n' % ((dims[0] - 1) * (dims[1] - 1) *
                                        (dims[2] - 1))).encode())
        section(cells)
    data = b''.join(out)
    if cut:
        data = data[:len(data) - cut]
    with open(path, 'wb') as fp:
        fp.write(data)


def main():
    if len(sys.argv) != 2:
        sys.exit('usage: make-vtk.py OUTDIR')
    o = sys.argv[1]
    os.makedirs(os.path.join(o, 'series'), exist_ok=True)
    os.makedirs(os.path.join(o, 'pieces'), exist_ok=True)

    # .pvd: three steps, each in another encoding.
    times = ('0.5', '1.0', '2.5')
    kws = (dict(compressor=ZLIB), dict(), dict(encoding='base64'))
    for k in range(3):
        v = mv.floats(100 + k)
        mv.good(os.path.join(o, 'series'), 'step-%d' % k, v,
                spacing=(0.5, 2, 4), origin=(1, 2, 3), **kws[k])
        os.replace(os.path.join(o, 'series', 'step-%d.f32' % k),
                   os.path.join(o, 'series-%d.f32' % (k + 1)))
    sets = [(times[k], 0, 'series/step-%d.vti' % k) for k in range(3)]
    pvd(os.path.join(o, 'series.pvd'), sets)
    pvd(os.path.join(o, 'unsorted.pvd'), [sets[1], sets[2], sets[0]])
    pvd(os.path.join(o, 'bad-missing.pvd'),
        sets[:2] + [('2.5', 0, 'series/no-such-step.vti')])
    pvd(os.path.join(o, 'bad-parts.pvd'),
        [sets[0], ('0.5', 1, 'series/step-1.vti'), sets[2]])

    # .pvti: 2x2x1 pieces sharing the faces x = 2 and y = 1.
    v, w = mv.floats(200), mv.floats(201)
    exts = [(0, 2, 0, 1, 0, NZ - 1), (2, NX - 1, 0, 1, 0, NZ - 1),
            (0, 2, 1, NY - 1, 0, NZ - 1), (2, NX - 1, 1, NY - 1, 0, NZ - 1)]
    encs = [dict(compressor=ZLIB), dict(fmt='binary'), dict(fmt='ascii'),
            dict()]
    pieces = []
    for i, (e, kw) in enumerate(zip(exts, encs)):
        fmt = kw.pop('fmt', 'appended')
        name = 'pieces/p%d.vti' % i
        mv.vti(os.path.join(o, name),
               [mv.arr('v', sub(v, e), fmt=fmt), mv.arr('w', sub(w, e),
                                                         fmt=fmt)],
               extent=e, spacing=(0.5, 2, 4), origin=(1, 2, 3), scalars='v',
               **kw)
        pieces.append((e, name))
    pvti(os.path.join(o, 'pieces.pvti'), pieces)
    mv.write_f32(o, 'pieces', mv.expected(v, 'Float32'))
    mv.write_f32(o, 'pieces-w', mv.expected(w, 'Float32'))
    pvti(os.path.join(o, 'bad-piece.pvti'),
         pieces[:3] + [(exts[3], 'pieces/no-such-piece.vti')])
    pvti(os.path.join(o, 'bad-hole.pvti'), pieces[:3])

    # Legacy .vtk.
    a = mv.floats(300)
    legacy(os.path.join(o, 'ascii-float.vtk'), [('SCALARS', 'v', 'float', a)],
           False, spacing=(0.5, 2, 4), origin=(1, 2, 3))
    mv.write_f32(o, 'ascii-float', mv.expected(a, 'Float32'))
    b = mv.floats(301)
    legacy(os.path.join(o, 'binary-float.vtk'),
           [('SCALARS', 'v', 'float', b)], True)
    mv.write_f32(o, 'binary-float', mv.expected(b, 'Float32'))
    s = mv.ints(302, -32768, 32767)
    legacy(os.path.join(o, 'binary-short.vtk'),
           [('SCALARS', 'v', 'short', s)], True)
    mv.write_f32(o, 'binary-short', mv.expected(s, 'Int16'))
    c = mv.floats(303, scale=1e5)
    vec = mv.floats(304, n=3 * N)
    cell = mv.floats(305, n=(NX - 1) * (NY - 1) * (NZ - 1))
    legacy(os.path.join(o, 'two-scalars.vtk'),
           [('SCALARS', 'a', 'float', b), ('VECTORS', 'vel', 'float', vec),
            ('SCALARS', 'b', 'double', c)], True,
           cells=[('SCALARS', 'c', 'float', cell)], field=True)
    mv.write_f32(o, 'two-scalars', mv.expected(b, 'Float32'))
    mv.write_f32(o, 'two-scalars-b', mv.expected(c, 'Float64'))
    mv.write_f32(o, 'two-scalars-vel', mv.magnitudes(vec, 'Float32', 3))
    vectors(o)
    legacy(os.path.join(o, 'bad-dims.vtk'), [('SCALARS', 'v', 'float', b)],
           True, dims=(NX, NY, NZ + 1), npoints=N)
    legacy(os.path.join(o, 'bad-count.vtk'), [('SCALARS', 'v', 'float',
                                                a[:N - 5])], False)
    legacy(os.path.join(o, 'bad-truncated.vtk'),
           [('SCALARS', 'v', 'float', b)], True, cut=41)
    legacy(os.path.join(o, 'bad-polydata.vtk'),
           [('SCALARS', 'v', 'float', b)], True, dataset='POLYDATA')


def vectors(o):
    """The legacy and .pvti fixtures of several components."""
    vec = mv.floats(400, n=3 * N)
    vec[3:6] = [3e38, 1e38, -1e38]   # squares past float32, the length not
    legacy(os.path.join(o, 'vectors-ascii.vtk'),
           [('VECTORS', 'vel', 'float', vec)], False)
    mv.write_f32(o, 'vectors-ascii', mv.magnitudes(vec, 'Float32', 3))
    s3 = mv.ints(401, -32768, 32767, n=3 * N)
    legacy(os.path.join(o, 'scalars3.vtk'),
           [('SCALARS', 'v3', 'short', s3, 3)], True)
    mv.write_f32(o, 'scalars3', mv.magnitudes(s3, 'Int16', 3))
    a, p, grad = mv.floats(402), mv.floats(403, scale=1e5), \
        mv.floats(404, n=2 * N)
    cf = mv.floats(405, n=(NX - 1) * (NY - 1) * (NZ - 1))
    for name, binary in (('field', True), ('field-ascii', False)):
        legacy(os.path.join(o, name + '.vtk'),
               [('SCALARS', 'a', 'float', a),
                ('FIELD', 'FieldData', None, [('p', 1, 'double', p),
                                              ('grad', 2, 'float', grad)])],
               binary, cells=[('FIELD', 'CellF', None,
                               [('cf', 1, 'float', cf)])])
    mv.write_f32(o, 'field', mv.magnitudes(grad, 'Float32', 2))
    mv.write_f32(o, 'field-p', mv.expected(p, 'Float64'))

    # .pvti of vectors: 2x2x1 pieces, each in another encoding.
    v3 = mv.floats(406, n=3 * N)
    exts = [(0, 2, 0, 1, 0, NZ - 1), (2, NX - 1, 0, 1, 0, NZ - 1),
            (0, 2, 1, NY - 1, 0, NZ - 1), (2, NX - 1, 1, NY - 1, 0, NZ - 1)]
    encs = [dict(compressor=ZLIB), dict(fmt='binary'), dict(fmt='ascii'),
            dict(encoding='base64')]
    pieces = []
    for i, (e, kw) in enumerate(zip(exts, encs)):
        fmt = kw.pop('fmt', 'appended')
        name = 'pieces/vec%d.vti' % i
        pts = sub(list(range(N)), e)
        mv.vti(os.path.join(o, name),
               [mv.arr('vel', [v3[3 * k + c] for k in pts for c in range(3)],
                       fmt=fmt, ncomp=3)],
               extent=e, spacing=(0.5, 2, 4), origin=(1, 2, 3), **kw)
        pieces.append((e, name))
    parr = ['      <PDataArray type="Float32" Name="vel" '
            'NumberOfComponents="3"/>']
    pvti(os.path.join(o, 'vectors.pvti'), pieces, parrays=parr,
         active='Vectors="vel"')
    mv.write_f32(o, 'vectors', mv.magnitudes(v3, 'Float32', 3))
    e = exts[3]
    mv.vti(os.path.join(o, 'pieces/vec-bad.vti'),
           [mv.arr('vel', mv.floats(407, n=2 * len(sub(list(range(N)), e))),
                   ncomp=2)], extent=e)
    pvti(os.path.join(o, 'bad-vectors.pvti'),
         pieces[:3] + [(e, 'pieces/vec-bad.vti')], parrays=parr,
         active='Vectors="vel"')


if __name__ == '__main__':
    main()
