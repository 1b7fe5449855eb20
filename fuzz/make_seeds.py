#!/usr/bin/env python3
"""Writes the checked-in seeds of the file-reader and spec fuzz targets.

Reader seeds go in tests/fuzz_seeds/testdata/, where each reader target takes the files of its
formats by extension (as it takes the bad-input files of tests/bad_input/testdata/); point-cloud
files live only in a tests/*/testdata folder. The spec seeds, which have no extension, keep a
corpus directory (fuzz/testdata/corpus/).

Small files that between them use every feature each reader documents (core/io/*_reader.h):
ascii and binary encodings, both byte orders, padding fields, organized clouds with NaN,
comments, headers, polygons and index styles. libFuzzer mutates from these; ../shared/data adds
real ModelNet10 PCD and DALES XYZ files at run time (fuzz/run_fuzzers.sh). Re-run after
changing it: python3 fuzz/make_seeds.py
"""
import math
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def points(n, seed=1):
    # a twisted, squashed helix: deterministic, not symmetric
    return [(math.cos(0.3 * i + seed) * (1 + 0.02 * i), 0.5 * math.sin(0.37 * i),
             0.01 * i * i - 0.2) for i in range(n)]


def write(target, name, data):
    spec = target == 'descriptor_spec_fuzzer'
    d = (os.path.join(HERE, 'testdata', 'corpus', target) if spec else
         os.path.join(HERE, '..', 'tests', 'fuzz_seeds', 'testdata'))
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), 'wb') as f:
        f.write(data.encode() if isinstance(data, str) else data)


def lzf(raw):
    """LZF as literal runs (a control byte < 32 is a run of control + 1 bytes), except that
    8 final bytes equal to the 8 before them become one back-reference, the decoder's other
    path: control (8 - 2) << 5, then the distance - 1."""
    out = bytearray()
    backref = len(raw) >= 16 and raw[-8:] == raw[-16:-8]
    body = raw[:-8] if backref else raw
    for i in range(0, len(body), 32):
        chunk = body[i:i + 32]
        out.append(len(chunk) - 1)
        out += chunk
    if backref:
        out += bytes([6 << 5, 7])
    return bytes(out)


def pcd_header(fields, sizes, types, counts, width, height, data, version='.7'):
    h = '# .PCD v%s - Point Cloud Data file format\nVERSION %s\n' % (version, version)
    h += 'FIELDS %s\nSIZE %s\nTYPE %s\n' % (' '.join(fields), ' '.join(map(str, sizes)),
                                            ' '.join(types))
    if counts is not None:
        h += 'COUNT %s\n' % ' '.join(map(str, counts))
    h += 'WIDTH %d\nHEIGHT %d\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS %d\nDATA %s\n' % (
        width, height, width * height, data)
    return h


def pcd_seeds():
    p = points(10)
    write('pcd_fuzzer', 'ascii_xyz.pcd',
          pcd_header('x y z'.split(), [4] * 3, 'FFF', [1] * 3, 10, 1, 'ascii') +
          ''.join('%.6g %.6g %.6g\n' % q for q in p))
    organized = ['%.6g %.6g %.6g %d\n' % (q + (0xff8000 + i,)) for i, q in enumerate(p[:6])]
    organized += ['nan nan nan 0\n', 'nan nan nan 0\n']
    write('pcd_fuzzer', 'ascii_organised_rgb_nan.pcd',
          pcd_header('x y z rgb'.split(), [4] * 4, 'FFFU', [1] * 4, 4, 2, 'ascii') +
          ''.join(organized))
    write('pcd_fuzzer', 'binary_xyz.pcd',
          (pcd_header('x y z'.split(), [4] * 3, 'FFF', [1] * 3, 10, 1, 'binary')).encode() +
          b''.join(struct.pack('<3f', *q) for q in p))
    write('pcd_fuzzer', 'binary_padding_intensity.pcd',
          (pcd_header('x y z _ intensity'.split(), [4, 4, 4, 1, 2], 'FFFUU', [1, 1, 1, 2, 1],
                      10, 1, 'binary')).encode() +
          b''.join(struct.pack('<3f2BH', *q, 0, 0, 7 * i) for i, q in enumerate(p)))
    write('pcd_fuzzer', 'binary_double_v06.pcd',
          (pcd_header('x y z'.split(), [8] * 3, 'FFF', None, 10, 1, 'binary',
                      version='.6')).encode() +
          b''.join(struct.pack('<3d', *q) for q in p))
    # binary_compressed: the x, y and z arrays one after the other (PCL's layout), LZF-coded;
    # the last four z repeat (a, b, a, b) so that the coder uses a back-reference.
    q = points(12)
    q[10] = q[10][:2] + (q[8][2],)
    q[11] = q[11][:2] + (q[9][2],)
    soa = b''.join(struct.pack('<12f', *[v[axis] for v in q]) for axis in range(3))
    compressed = lzf(soa)
    write('pcd_fuzzer', 'binary_compressed.pcd',
          pcd_header('x y z'.split(), [4] * 3, 'FFF', [1] * 3, 12, 1, 'binary_compressed')
          .encode() + struct.pack('<II', len(compressed), len(soa)) + compressed)


def ply_seeds():
    p = points(8)
    write('ply_fuzzer', 'ascii_vertices.ply',
          'ply\nformat ascii 1.0\ncomment made by make_reader_seeds.py\nelement vertex 8\n'
          'property float x\nproperty float y\nproperty float z\nproperty uchar red\n'
          'end_header\n' + ''.join('%.6g %.6g %.6g %d\n' % (q + (i * 30,)) for i, q in
                                   enumerate(p)))
    header = ('ply\nformat binary_little_endian 1.0\nobj_info seeds\nelement vertex 8\n'
              'property double x\nproperty double y\nproperty double z\n'
              'property float nx\nproperty float ny\nproperty float nz\n'
              'element face 6\nproperty list uchar int vertex_indices\n'
              'element edge 1\nproperty int vertex1\nproperty int vertex2\nend_header\n')
    cube = [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4),
             (1, 5, 7, 3)]
    body = b''.join(struct.pack('<3d3f', *v, 0, 0, 1) for v in cube)
    body += b''.join(struct.pack('<B4i', 4, *f) for f in faces)
    body += struct.pack('<2i', 0, 1)
    write('ply_fuzzer', 'binary_le_cube_faces.ply', header.encode() + body)
    header = ('ply\nformat binary_big_endian 1.0\nelement vertex 8\nproperty float32 x\n'
              'property float32 y\nproperty float32 z\nproperty uint8 alpha\n'
              'element face 2\nproperty list uint8 uint32 vertex_index\nend_header\n')
    body = b''.join(struct.pack('>3fB', *q, 255) for q in p)
    body += struct.pack('>B3I', 3, 0, 1, 2) + struct.pack('>B5I', 5, 3, 4, 5, 6, 7)
    write('ply_fuzzer', 'binary_be_polygons.ply', header.encode() + body)
    write('ply_fuzzer', 'ascii_faces.ply',
          'ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n'
          'property float z\nelement face 2\nproperty list uchar int vertex_indices\n'
          'end_header\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 2 3\n')


def off_seeds():
    write('off_fuzzer', 'tetrahedron.off',
          'OFF\n# a comment\n4 4 6\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n3 0 1 3\n'
          '3 0 2 3\n3 1 2 3\n')
    write('off_fuzzer', 'modelnet_quirk_quads_colors.off',
          'OFF8 6 0\n' + ''.join('%d %d %d\n' % v for v in
                                 [(x, y, z) for x in (0, 2) for y in (0, 1) for z in (0, 3)]) +
          '4 0 1 3 2 255 0 0\n4 4 6 7 5 0 255 0\n4 0 4 5 1\n4 2 3 7 6\n4 0 2 6 4\n4 1 5 7 3\n')
    write('off_fuzzer', 'pentagon_fan.off',
          'OFF\n5 1 0\n' + ''.join('%.6g %.6g 0.5\n' % (math.cos(a), math.sin(a)) for a in
                                   [2 * math.pi * k / 5 for k in range(5)]) + '5 0 1 2 3 4\n')


def obj_seeds():
    write('obj_fuzzer', 'cube_slashes.obj',
          '# cube\nmtllib none.mtl\no cube\n' +
          ''.join('v %d %d %d\n' % v for v in
                  [(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)]) +
          'vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\ng side\nusemtl red\ns off\n'
          'f 1/1/1 2/2/1 4/3/1 3/1/1\nf 5//1 7//1 8//1 6//1\nf 1/1 5/2 6/3 2/1\n'
          'f -6 -5 -1 -2\nf 1 3 7 5\nf 2 6 8 4\n')
    write('obj_fuzzer', 'points_only.obj',
          ''.join('v %.6g %.6g %.6g\n' % q for q in points(12)))
    write('obj_fuzzer', 'triangles_with_color.obj',
          'v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nv 0 0 1 1 1 1\nf 1 2 3\nf 1 3 4\n'
          'l 1 2\n')


def xyz_seeds():
    p = points(12)
    write('xyz_fuzzer', 'blank.xyz', ''.join('%.6f %.6f %.6f\n' % q for q in p))
    write('xyz_fuzzer', 'header_commas_extra.csv',
          'x,y,z,intensity\n' + ''.join('%.6f,%.6f,%.6f,%d\n' % (q + (i,)) for i, q in
                                        enumerate(p)))
    write('xyz_fuzzer', 'semicolon_decimal_comma.csv',
          ''.join(('%.4f;%.4f;%.4f\n' % q).replace('.', ',') for q in p))
    write('xyz_fuzzer', 'comments_crlf_nan.txt',
          '# scan 7\r\n' + ''.join('%.6g\t%.6g  %.6g # ok\r\n' % q for q in p[:6]) +
          'nan 1 2\r\n\r\n1e3 -2.5E-2 inf\r\n')
    write('xyz_fuzzer', 'georeferenced.xyz',
          ''.join('%.3f %.3f %.3f\n' % (527000 + q[0], 5410000 + q[1], 220 + q[2]) for q in p))


def open3d_text_and_gzip_seeds():
    # Open3D's and Leica's text formats, and gzip around a PCD and a text file (gzip_fuzzer)
    import gzip
    p = points(10)
    write('xyz_fuzzer', 'leica_two_scans.pts',
          '6\n' + ''.join('%.5f %.5f %.5f 12 200 100 50\n' % q for q in p[:6]) +
          '4\n' + ''.join('%.5f %.5f %.5f 9 0 0 0\n' % q for q in p[6:]))
    write('xyz_fuzzer', 'open3d_normals.xyzn', ''.join('%.10f %.10f %.10f 0 0 1\n' % q for q in p))
    write('xyz_fuzzer', 'open3d_colors.xyzrgb',
          ''.join('%.10f %.10f %.10f 0.5 0.25 1\n' % q for q in p))
    text = ''.join('%.6f %.6f %.6f\n' % q for q in p).encode()
    write('gzip_fuzzer', 'text_in_gzip.xyz.gz', gzip.compress(text, mtime=0))
    body = b''.join(struct.pack('<3f', *q) for q in p)
    pcd = pcd_header('xyz', [4, 4, 4], 'FFF', [1, 1, 1], len(p), 1, 'binary').encode() + body
    write('gzip_fuzzer', 'binary_in_gzip.pcd.gz', gzip.compress(pcd, mtime=0))
    write('gzip_fuzzer', 'two_members.xyz.gz',
          gzip.compress(text[:40], mtime=0) + gzip.compress(text[40:], mtime=0))


def spec_seeds():
    # as users type them (core/descriptor_spec.h), every kind and parameter at least once
    specs = [
        'dfsd', 'rphsd', 'comsd', 'cnsd',
        'rphsd:refs=cubic27,bins=100,variant=complete',
        'rphsd:refs=cross7,bins=10,variant=reduced',
        'rphsd:refs=fibonacci:100,bins=37',
        'rphsd:refs=spherical27,bins=20',
        'rphsd:refs=[0,0,0;1,0,0;0,1,0;0.5,0.5,0.5]',
        'comsd:grid=50', 'comsd:grid=8',
        'cnsd:t_start=0.05,t_end=0.95,t_step=0.05,max_points=8000,downsample=voxel,seed=0',
        'cnsd:t_step=0.1,downsample=random,seed=42,max_points=500',
        'dfsd:grid=12,order=8,frame=box,fields=both,size=0,up=z',
        'dfsd:grid=4,order=2,frame=pca,fields=isotropic,up=-y',
        'dfsd:frame=upright,fields=anisotropic,size=1.5,up=x',
        'dfsd:frame=upright,smooth=0.25', 'dfsd:smooth=0.015',
    ]
    for i, spec in enumerate(specs):
        write('descriptor_spec_fuzzer', 'spec%02d' % i, spec)


if __name__ == '__main__':
    spec_seeds()
    pcd_seeds()
    ply_seeds()
    off_seeds()
    obj_seeds()
    xyz_seeds()
    open3d_text_and_gzip_seeds()
