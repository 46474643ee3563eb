#!/usr/bin/env python3
"""Read a tetfsi checkpoint (core/checkpoint.hpp's format, version 1) into numpy arrays.

    python3 scripts/read_checkpoint.py OUT/checkpoints/step_000040.tfck          # list records
    python3 scripts/read_checkpoint.py FILE sim/solid/body/0/displacement        # print one

As a module: `records = read_checkpoint(path)` gives {key: numpy array | str | scipy-free
(rows, cols, indptr, indices, data) tuple for sparse records}. Every record's CRC-32 is
checked (zlib.crc32), as tetfsi does; a bad file raises ValueError naming the record.
"""
import struct
import sys
import zlib

import numpy as np

MAGIC, END = b"TETFSICK", b"TETFSEND"
DTYPES = {1: "<f8", 2: "<i4", 3: "i1", 4: "u1", 5: "<i8"}
TYPE_NAMES = {1: "f64", 2: "i32", 3: "i8", 4: "u8", 5: "i64", 6: "text", 7: "sparse"}


def read_checkpoint(path):
    data = open(path, "rb").read()
    if data[:8] != MAGIC:
        raise ValueError(f"{path}: not a tetfsi checkpoint")
    version, _, count = struct.unpack_from("<IIQ", data, 8)
    if version != 1:
        raise ValueError(f"{path}: format version {version}, this script reads 1")
    at, records, crcs = 24, {}, []
    for _ in range(count):
        start = at
        (klen,) = struct.unpack_from("<I", data, at)
        key = data[at + 4:at + 4 + klen].decode()
        at += 4 + klen
        rtype, _, _, rows, cols, nbytes = struct.unpack_from("<BBHQQQ", data, at)
        at += 28
        payload = data[at:at + nbytes]
        (crc,) = struct.unpack_from("<I", data, at + nbytes)
        if zlib.crc32(data[start:at + nbytes]) != crc:
            raise ValueError(f"{path}: record '{key}' is corrupt (CRC-32 mismatch)")
        at += nbytes + 4
        crcs.append(crc)
        if rtype in DTYPES:
            records[key] = np.frombuffer(payload, DTYPES[rtype]).reshape(rows, cols).squeeze(1) \
                if cols == 1 else np.frombuffer(payload, DTYPES[rtype]).reshape(rows, cols)
        elif rtype == 6:
            records[key] = payload.decode()
        else:
            (nnz,) = struct.unpack_from("<Q", payload, 0)
            indptr = np.frombuffer(payload, "<i4", cols + 1, 8)
            indices = np.frombuffer(payload, "<i4", nnz, 8 + 4 * (cols + 1))
            values = np.frombuffer(payload, "<f8", nnz, 8 + 4 * (cols + 1 + nnz))
            records[key] = (rows, cols, indptr, indices, values)  # CSC
    if data[at:at + 8] != END or zlib.crc32(struct.pack(f"<{len(crcs)}I", *crcs)) != \
            struct.unpack_from("<I", data, at + 16)[0]:
        raise ValueError(f"{path}: its end marker does not match its records")
    return records


def describe(value):
    if isinstance(value, str):
        return f"text, {len(value)} chars"
    if isinstance(value, tuple):
        return f"sparse {value[0]} x {value[1]}, {len(value[4])} non-zeros"
    return f"{value.dtype} {' x '.join(map(str, value.shape)) or 'scalar'}"


def main(argv):
    if len(argv) < 2:
        print(__doc__.strip().splitlines()[2:4], file=sys.stderr)
        return 2
    records = read_checkpoint(argv[1])
    if len(argv) > 2:
        print(records[argv[2]])
        return 0
    for key, value in records.items():
        print(f"{key:48s} {describe(value)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
