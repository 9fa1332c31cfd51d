#!/usr/bin/env python3
"""A black W x H EXR (uncompressed scanlines, f32 B G R): the reference that
gpu_watertight.sh compares its renders with."""
import struct, sys
w, h, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
def attr(name, typ, data):
    return name.encode() + b'\0' + typ.encode() + b'\0' + struct.pack('<i', len(data)) + data
ch = b''.join(c + b'\0' + struct.pack('<i', 2) + b'\0\0\0\0' + struct.pack('<ii', 1, 1) for c in (b'B', b'G', b'R')) + b'\0'
head = b'\x76\x2f\x31\x01' + struct.pack('<i', 2)
head += attr('channels', 'chlist', ch)
head += attr('compression', 'compression', b'\0')
head += attr('dataWindow', 'box2i', struct.pack('<4i', 0, 0, w - 1, h - 1))
head += attr('displayWindow', 'box2i', struct.pack('<4i', 0, 0, w - 1, h - 1))
head += attr('lineOrder', 'lineOrder', b'\0')
head += attr('pixelAspectRatio', 'float', struct.pack('<f', 1.0))
head += attr('screenWindowCenter', 'v2f', struct.pack('<ff', 0, 0))
head += attr('screenWindowWidth', 'float', struct.pack('<f', 1.0))
head += b'\0'
line = w * 3 * 4
start = len(head) + 8 * h
offs = b''.join(struct.pack('<Q', start + y * (8 + line)) for y in range(h))
body = b''.join(struct.pack('<ii', y, line) + bytes(line) for y in range(h))
open(out, 'wb').write(head + offs + body)
