"""Camber network in a ski's HDF5 file: write (atomically) and read the ``network`` group."""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path

from skisnow.app.storage.skis import replace_ski_group
from skisnow.solvers import camber
from skisnow.solvers.errors import DataFileError

__all__ = ["read_network_from_ski", "write_network_to_ski"]


def write_network_to_ski(path: str | os.PathLike, network: Mapping[str, object]) -> None:
    """Store ``network`` as the ``network`` group of an existing ski HDF5 file, atomically.

    The file is copied beside itself, the group replaced in the copy, and the copy renamed onto
    the original only on success; the rest of the file (measurements, provenance of the ski) is
    untouched. Same group layout as :func:`app.storage.skis.write_ski`: arrays as datasets,
    ``network["attrs"]`` as attributes.
    """
    replace_ski_group(path, "network", camber.network_to_dict(network))


def read_network_from_ski(path: str | os.PathLike) -> dict:
    """Read the ``network`` group of a ski HDF5 file into a network dict."""
    import h5py

    path = Path(path)
    if not path.is_file():
        raise DataFileError(f"ski file not found: {path}")
    with h5py.File(path, "r") as fh:
        if "network" not in fh:
            raise DataFileError(f"{path} has no camber network (run skisnow train-camber)")
        grp = fh["network"]
        net: dict = {key: grp[key][()] for key in grp}
        net["attrs"] = dict(grp.attrs)
    return camber.network_to_dict(net)
