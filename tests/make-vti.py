#!/usr/bin/env python3
"""make-vti.py OUTDIR: writes the VTK XML ImageData fixtures of
tests/test-vti.c into OUTDIR, from the standard library only (zlib, base64,
struct).  make-vti.py --big OUTDIR: the larger grids of its box reads
(big-*.vti, no .f32: a box must equal the same box of the whole read).

Every good file NAME.vti has NAME.f32 beside it: the values a reader must
give, as little-endian float32, x fastest.  bad-*.vti are files a reader
must refuse.  vec-*.vti hold an array of several components per point,
read with --magnitude (tvpal_input_opts.magnitude): NAME.f32 is each
point's length, the squares of its components (as stored) summed left to
right in double, the root rounded to float32.  The layouts follow the VTK XML format: binary data start with
a header of header_type integers, [nbytes] uncompressed or [nblocks,
blocksize, lastblocksize, csize_1..n] compressed; base64 encodes an
uncompressed header together with its data, a compressed header apart
from its blocks.
"""
import base64
import math
import os
import struct
import sys
import zlib

NX, NY, NZ = 5, 4, 3
N = NX * NY * NZ
EXTENT = (0, NX - 1, 0, NY - 1, 0, NZ - 1)
BLOCK = 64          # compressed block size in bytes: 240 bytes of float32
                    # make 4 blocks, the last one short (48 bytes)

CODES = {'Float32': 'f', 'Float64': 'd', 'Int8': 'b', 'UInt8': 'B',
         'Int16': 'h', 'UInt16': 'H', 'Int32': 'i', 'UInt32': 'I'}


def f32(v):
    """v rounded to float32, as a Python float."""
    return struct.unpack('<f', struct.pack('<f', v))[0]


def lcg(seed):
    x = seed
    while True:
        x = (x * 6364136223846793005 + 1442695040888963407) % 2 ** 64
        yield (x >> 11) / 2 ** 53


def floats(seed, n=N, scale=200.0):
    g = lcg(seed)
    return [(next(g) - 0.5) * scale for _ in range(n)]


def ints(seed, lo, hi, n=N):
    g = lcg(seed)
    v = [lo + int(next(g) * (hi - lo + 1)) for _ in range(n)]
    v[0], v[1] = lo, hi
    return v


def pack(values, vtype, be):
    return struct.pack(('>' if be else '<') + CODES[vtype] * len(values),
                       *values)


def binary_parts(raw, header, be, compress, corrupt=False):
    """(header bytes, data bytes) of one array's binary data."""
    e, w = ('>' if be else '<'), ('Q' if header == 64 else 'I')
    if not compress:
        return struct.pack(e + w, len(raw)), raw
    blocks = [raw[i:i + BLOCK] for i in range(0, len(raw), BLOCK)]
    comp = [zlib.compress(b) for b in blocks]
    if corrupt:   # block 2: keep the zlib header, scramble the deflate data
        comp[1] = comp[1][:2] + bytes(c ^ 0x5A for c in comp[1][2:])
    last = len(blocks[-1]) if len(blocks[-1]) != BLOCK else 0
    hdr = struct.pack(e + w * (3 + len(comp)), len(comp), BLOCK, last,
                      *[len(c) for c in comp])
    return hdr, b''.join(comp)


def b64(hdr, data, compress, joint=False):
    """VTK's base64: one stream uncompressed, header and blocks apart when
    compressed (joint: one stream anyway, as some other writers do)."""
    if not compress or joint:
        return base64.b64encode(hdr + data)
    return base64.b64encode(hdr) + base64.b64encode(data)


def text_of(values, vtype):
    if vtype in ('Float32', 'Float64'):
        return ' '.join(repr(float(v)) for v in values)
    return ' '.join(str(v) for v in values)


def expected(values, vtype):
    if vtype == 'Float32':
        return [f32(v) for v in values]
    return [f32(float(v)) for v in values]


def arr(name, values, vtype='Float32', fmt='appended', ncomp=1, **kw):
    d = dict(name=name, values=values, type=vtype, format=fmt, ncomp=ncomp)
    d.update(kw)
    return d


def vti(path, arrays, cells=(), byte_order='LittleEndian', header=32,
        header_attr=True, compressor=None, extent=EXTENT, origin=(0, 0, 0),
        spacing=(1, 1, 1), direction=None, scalars=None, encoding='raw',
        offset_fix=None, pieces=1):
    be = byte_order == 'BigEndian'
    compress = compressor is not None
    appended = b''
    attrs = 'type="ImageData" version="1.0" byte_order="%s"' % byte_order
    if header_attr:
        attrs += ' header_type="UInt%d"' % header
    if compressor:
        attrs += ' compressor="%s"' % compressor
    ext = ' '.join(str(e) for e in extent)
    img = 'WholeExtent="%s" Origin="%s" Spacing="%s"' % (
        ext, ' '.join(repr(float(o)) for o in origin),
        ' '.join(repr(float(s)) for s in spacing))
    if direction:
        img += ' Direction="%s"' % ' '.join(str(x) for x in direction)
    out = ['<?xml version="1.0"?>',
           '<!-- written by tvpal tests/make-vti.py -->',
           '<VTKFile %s>' % attrs, '  <ImageData %s>' % img]

    def data_arrays(arrays):
        nonlocal appended
        lines = []
        for a in arrays:
            head = '<DataArray type="%s" Name="%s" format="%s"' % (
                a['type'], a['name'], a['format'])
            if a['ncomp'] != 1:
                head += ' NumberOfComponents="%d"' % a['ncomp']
            body = ''
            if a['format'] == 'ascii':
                body = text_of(a['values'], a['type'])
            else:
                raw = pack(a['values'], a['type'], be)
                hdr, data = binary_parts(raw, header, be, compress,
                                         a.get('corrupt', False))
                if a['format'] == 'binary':
                    body = b64(hdr, data, compress,
                               a.get('joint', False)).decode()
                    if 'cut' in a:
                        body = body[:a['cut']]
                else:
                    off = len(appended)
                    if offset_fix is not None:
                        off = offset_fix
                    head += ' offset="%d"' % off
                    if encoding == 'raw':
                        appended += hdr + data
                    else:
                        appended += b64(hdr, data, compress)
            lines.append('        %s>' % head)
            key = ('          <InformationKey name="x" location="y" '
                   'length="1"><Value index="0">7</Value></InformationKey>')
            if a.get('infokey'):
                lines.append(key)
            if body:
                lines.append('          ' + body)
            if a.get('infokey_after'):   # as VTK 9 writes a vector's range
                lines.append(key)
            lines.append('        </DataArray>')
        return lines

    for p in range(pieces):
        if pieces == 1:
            pext = ext
        else:   # split z between the pieces
            z0, z1 = extent[4], extent[5]
            zm = (z0 + z1) // 2
            pext = ' '.join(str(e) for e in extent[:4] +
                            ((z0, zm) if p == 0 else (zm, z1)))
        out.append('    <Piece Extent="%s">' % pext)
        out.append('      <PointData%s>' % (
            ' Scalars="%s"' % scalars if scalars else ''))
        out += data_arrays(arrays)
        out.append('      </PointData>')
        out.append('      <CellData>')
        out += data_arrays(cells)
        out.append('      </CellData>')
        out.append('    </Piece>')
    out.append('  </ImageData>')
    text = ('\n'.join(out) + '\n').encode()
    if appended:
        text += b'  <AppendedData encoding="%s">\n   _' % encoding.encode()
        text += appended + b'\n  </AppendedData>\n'
    text += b'</VTKFile>\n'
    with open(path, 'wb') as f:
        f.write(text)
    return text


def good(outdir, name, values, vtype='Float32', **kw):
    """NAME.vti with one array v of values, and NAME.f32."""
    fmt = kw.pop('fmt', 'appended')
    extra = {k: kw.pop(k) for k in ('joint', 'infokey') if k in kw}
    vti(os.path.join(outdir, name + '.vti'),
        [arr('v', values, vtype, fmt, **extra)], **kw)
    write_f32(outdir, name, expected(values, vtype))


def magnitudes(values, vtype, ncomp):
    """The length of each point of ncomp values, as --magnitude reads it:
    the components as stored, their squares summed in order in double, the
    root rounded to float32."""
    stored = [f32(v) for v in values] if vtype == 'Float32' else values
    out = []
    for i in range(0, len(stored), ncomp):
        s = 0.0
        for c in stored[i:i + ncomp]:
            s = s + float(c) * float(c)
        out.append(f32(math.sqrt(s)))
    return out


def vec(outdir, name, values, vtype='Float32', ncomp=3, **kw):
    """NAME.vti with one array vel of ncomp components, and NAME.f32 of
    its lengths."""
    fmt = kw.pop('fmt', 'appended')
    extra = {k: kw.pop(k) for k in ('infokey_after',) if k in kw}
    vti(os.path.join(outdir, name + '.vti'),
        [arr('vel', values, vtype, fmt, ncomp=ncomp, **extra)], **kw)
    write_f32(outdir, name, magnitudes(values, vtype, ncomp))


def write_f32(outdir, name, vals):
    with open(os.path.join(outdir, name + '.f32'), 'wb') as f:
        f.write(struct.pack('<%df' % len(vals), *vals))


def main():
    if len(sys.argv) != 2:
        sys.exit('usage: make-vti.py OUTDIR')
    o = sys.argv[1]
    os.makedirs(o, exist_ok=True)
    v = floats(1)
    # The awkward values: zero, negative zero, the smallest denormal, NaN,
    # infinity, the largest float32.
    special = list(v)
    special[:6] = [0.0, -0.0, struct.unpack('<f', b'\1\0\0\0')[0],
                   float('nan'), float('inf'), f32(3.4028234663852886e38)]

    good(o, 'ascii', special, fmt='ascii', header_attr=False)
    good(o, 'ascii-infokey', v, fmt='ascii', infokey=True)
    good(o, 'binary', v, fmt='binary')
    good(o, 'binary64', v, fmt='binary', header=64)
    good(o, 'binary-zlib', v, fmt='binary', compressor='vtkZLibDataCompressor')
    good(o, 'binary-zlib64', v, fmt='binary', header=64,
         compressor='vtkZLibDataCompressor')
    good(o, 'binary-zlib-joint', v, fmt='binary', joint=True,
         compressor='vtkZLibDataCompressor')
    good(o, 'appended-raw', special, header_attr=False)
    good(o, 'appended-raw64', v, header=64)
    good(o, 'appended-zlib', v, compressor='vtkZLibDataCompressor')
    good(o, 'appended-zlib64', special, header=64,
         compressor='vtkZLibDataCompressor')
    good(o, 'appended-b64', v, encoding='base64')
    good(o, 'appended-b64-64', v, encoding='base64', header=64)
    good(o, 'appended-b64-zlib', v, encoding='base64',
         compressor='vtkZLibDataCompressor')
    good(o, 'appended-b64-zlib64', v, encoding='base64', header=64,
         compressor='vtkZLibDataCompressor')
    good(o, 'bigendian-raw', special, byte_order='BigEndian')
    good(o, 'bigendian-zlib64', v, byte_order='BigEndian', header=64,
         compressor='vtkZLibDataCompressor')
    good(o, 'bigendian-binary', v, fmt='binary', byte_order='BigEndian')
    good(o, 'float64', floats(2, scale=1e6), 'Float64',
         compressor='vtkZLibDataCompressor')
    good(o, 'float64-be', floats(3, scale=1e-3), 'Float64',
         byte_order='BigEndian', fmt='binary')
    good(o, 'float64-ascii', floats(4), 'Float64', fmt='ascii')
    good(o, 'int16', ints(5, -32768, 32767), 'Int16')
    good(o, 'int16-be', ints(6, -32768, 32767), 'Int16',
         byte_order='BigEndian', compressor='vtkZLibDataCompressor')
    good(o, 'uint16', ints(7, 0, 65535), 'UInt16', fmt='binary')
    good(o, 'uint8', ints(8, 0, 255), 'UInt8')
    good(o, 'int8', ints(9, -128, 127), 'Int8', fmt='ascii')
    good(o, 'int32', ints(10, -2 ** 31, 2 ** 31 - 1), 'Int32', fmt='binary')
    good(o, 'uint32', ints(11, 0, 2 ** 32 - 1), 'UInt32')
    good(o, 'grid', v, spacing=(0.5, 2, 4), origin=(1, 2, 3))
    good(o, 'extent', v, extent=(2, 6, -1, 2, 10, 12), spacing=(0.5, 2, 4),
         origin=(1, 2, 3))

    # Two point arrays (and a cell one): Scalars names b.
    a, b = floats(12), floats(13)
    c = floats(14, n=(NX - 1) * (NY - 1) * (NZ - 1))
    two = [arr('a', a, fmt='ascii'), arr('b', b)]
    vti(os.path.join(o, 'two-arrays.vti'), two,
        cells=[arr('c', c, fmt='binary')], scalars='b')
    write_f32(o, 'two-arrays', expected(b, 'Float32'))
    write_f32(o, 'two-arrays-a', expected(a, 'Float32'))
    vti(os.path.join(o, 'no-scalars.vti'), two)

    # Vectors (--magnitude): every encoding, types, 2 to 9 components; a
    # point is 12 bytes of float32 and blocks 64 bytes, so points straddle
    # the blocks' ends.
    w3 = floats(20, n=3 * N)
    w3[:6] = [0.0, -0.0, 3e38, float('nan'), 1.0, 2.0]  # NaN: a NaN point
    vec(o, 'vec-ascii', w3, fmt='ascii', infokey_after=True)
    vec(o, 'vec-binary', w3, fmt='binary', infokey_after=True)
    vec(o, 'vec-binary-zlib64', w3, fmt='binary', header=64,
        compressor='vtkZLibDataCompressor')
    vec(o, 'vec-raw', w3, scalars='vel')
    vec(o, 'vec-zlib', w3, compressor='vtkZLibDataCompressor')
    vec(o, 'vec-b64', w3, encoding='base64')
    vec(o, 'vec-b64-zlib', w3, encoding='base64',
        compressor='vtkZLibDataCompressor')
    vec(o, 'vec-be-float64', floats(21, n=2 * N, scale=1e30), 'Float64',
        ncomp=2, byte_order='BigEndian', compressor='vtkZLibDataCompressor')
    vec(o, 'vec-float64-ascii', floats(22, n=3 * N), 'Float64', fmt='ascii')
    vec(o, 'vec-int16', ints(23, -32768, 32767, n=3 * N), 'Int16')
    vec(o, 'vec-uint8-4', ints(24, 0, 255, n=4 * N), 'UInt8', ncomp=4,
        fmt='binary')
    vec(o, 'vec-int32-9', ints(25, -2 ** 31, 2 ** 31 - 1, n=9 * N), 'Int32',
        ncomp=9, compressor='vtkZLibDataCompressor')
    vti(os.path.join(o, 'bad-ncomp.vti'),
        [arr('vel', floats(26, n=257 * N), ncomp=257)])

    # Bad files.
    t = vti(os.path.join(o, 'bad-xml.vti'), [arr('v', v, fmt='ascii')])
    with open(os.path.join(o, 'bad-xml.vti'), 'wb') as f:
        f.write(t.replace(b'</PointData>', b'</PointDat>'))
    vti(os.path.join(o, 'bad-zlib.vti'), [arr('v', v, corrupt=True)],
        compressor='vtkZLibDataCompressor')
    vti(os.path.join(o, 'bad-offset.vti'), [arr('v', v)], offset_fix=100000)
    t = vti(os.path.join(o, 'bad-truncated.vti'), [arr('v', v)])
    with open(os.path.join(o, 'bad-truncated.vti'), 'wb') as f:
        f.write(t[:len(t) - 100])
    vti(os.path.join(o, 'bad-base64.vti'), [arr('v', v, fmt='binary', cut=100)])
    vti(os.path.join(o, 'bad-direction.vti'), [arr('v', v)],
        direction=(0, 1, 0, 1, 0, 0, 0, 0, 1))
    vti(os.path.join(o, 'bad-components.vti'),
        [arr('v', floats(15, n=2 * N), ncomp=2)])
    vti(os.path.join(o, 'bad-size.vti'), [arr('v', v[:N - 1])])
    vti(os.path.join(o, 'bad-pieces.vti'), [arr('v', v)], pieces=2)
    vti(os.path.join(o, 'bad-lz4.vti'), [arr('v', v)],
        compressor='vtkLZ4DataCompressor')
    t = vti(os.path.join(o, 'bad-polydata.vti'), [arr('v', v)])
    with open(os.path.join(o, 'bad-polydata.vti'), 'wb') as f:
        f.write(t.replace(b'type="ImageData"', b'type="PolyData"'))


def big(o):
    """Grids for box reads: raw rows past the 4 MiB a batch holds, zlib
    blocks whose size is not a multiple of the value size (values cut by
    a block's end), base64 longer than a 64 KiB piece, a converted type."""
    global BLOCK
    os.makedirs(o, exist_ok=True)

    def ext(nx, ny, nz):
        return (0, nx - 1, 0, ny - 1, 0, nz - 1)

    n = 160 * 128 * 64
    v = [((i * 7919) % 10007) * 0.01 - 50.0 for i in range(n)]
    zl = 'vtkZLibDataCompressor'
    vti(os.path.join(o, 'big-raw.vti'), [arr('v', v)],
        extent=ext(160, 128, 64))
    BLOCK = 32766
    vti(os.path.join(o, 'big-zlib.vti'), [arr('v', v[:96 * 80 * 48])],
        extent=ext(96, 80, 48), compressor=zl)
    BLOCK = 32764
    vti(os.path.join(o, 'big-zlib64-be.vti'),
        [arr('v', v[:64 * 48 * 40], 'Float64')], extent=ext(64, 48, 40),
        byte_order='BigEndian', header=64, compressor=zl)
    BLOCK = 1002
    vti(os.path.join(o, 'big-binary-zlib.vti'),
        [arr('v', v[:40 * 30 * 20], fmt='binary')], extent=ext(40, 30, 20),
        compressor=zl)
    vti(os.path.join(o, 'big-b64.vti'), [arr('v', v[:100 * 80 * 20])],
        extent=ext(100, 80, 20), encoding='base64')
    vti(os.path.join(o, 'big-int16.vti'),
        [arr('v', [int(x * 100) for x in v[:100 * 50 * 30]], 'Int16')],
        extent=ext(100, 50, 30))
    # Vectors: rows of 12-byte points past a batch's 4 MiB, blocks that cut
    # points, base64 longer than a piece.
    vti(os.path.join(o, 'big-vec-raw.vti'), [arr('v', v[:3 * 160 * 96 * 28],
                                                 ncomp=3)],
        extent=ext(160, 96, 28))
    vti(os.path.join(o, 'big-vec-zlib.vti'),
        [arr('v', v[:3 * 64 * 48 * 40], ncomp=3)], extent=ext(64, 48, 40),
        compressor=zl)
    vti(os.path.join(o, 'big-vec-b64-f64.vti'),
        [arr('v', v[:2 * 60 * 40 * 20], 'Float64', ncomp=2)],
        extent=ext(60, 40, 20), encoding='base64')


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == '--big':
        big(sys.argv[2])
    else:
        main()
