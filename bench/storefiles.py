"""The files of a specula store: its root and the data files under its data directory (docs/store-format.md).
Benchmarks cat these to warm the page cache or to measure the I/O ceiling of reading a store."""
import glob
import os

import h5py


def store_files(path):
    """The root, then every data file it links to (format 2); just the file for a format-1 store."""
    with h5py.File(path, "r") as f:
        data_dir = f.attrs.get("data_dir")
    if data_dir is None:
        return [path]
    if isinstance(data_dir, bytes):
        data_dir = data_dir.decode()
    d = os.path.join(os.path.dirname(os.path.abspath(path)), data_dir)
    return [path] + sorted(glob.glob(os.path.join(d, "objects", "**", "*.h5"), recursive=True))


def store_bytes(path):
    return sum(os.path.getsize(f) for f in store_files(path))


def remove_store(path):
    """Deletes a store's root and data directory (benchmark scratch stores)."""
    import shutil
    if os.path.exists(path):
        os.remove(path)
    shutil.rmtree(path + ".d", ignore_errors=True)
