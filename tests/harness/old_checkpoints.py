"""Checkpoint files as older versions of parmpm wrote them, for the readers' compatibility tests
(``tests/io/test_checkpoint_faults.py``) and the restart tests' old-format fixture
(``tests/driver/test_checkpoint_parts.py``)."""
from __future__ import annotations

import h5py
import numpy as np

from parmpm.io import checkpoint as ck
from parmpm.io.checkpoint import attrs_digest


def write_v3(path, data: dict, attrs: dict, block_rows: int = 1 << 16) -> None:
    """A version 3 file as version 3 wrote it: rows in global-id order, Fletcher-32 chunks of
    ``block_rows``, a SHA-256 per block, ``data_digest`` of the tables, ``digest`` of the
    attributes (also the restart tests' old-format fixture)."""
    n = next(iter(data.values())).shape[0]
    with h5py.File(path, "w") as f:
        f.attrs["format"] = ck.FORMAT
        f.attrs["version"] = 3
        for k, v in attrs.items():
            f.attrs[k] = v
        f.attrs["block_rows"] = block_rows
        tables = {}
        for k, v in data.items():
            v = np.ascontiguousarray(v, ck.DTYPES[k])
            f.create_dataset(f"particles/{k}", data=v, chunks=(min(n, block_rows),) + v.shape[1:],
                             fletcher32=True)
            tables[k] = np.frombuffer(b"".join(ck.block_digest(k, b, v[lo:lo + block_rows])
                                               for b, lo in enumerate(range(0, n, block_rows))),
                                      np.uint8).reshape(-1, 32)
            f[f"digests/{k}"] = tables[k]
        f.attrs["data_digest"] = ck.tables_digest(tables)
        f.attrs["digest"] = attrs_digest({k: v for k, v in f.attrs.items() if k != "digest"})
