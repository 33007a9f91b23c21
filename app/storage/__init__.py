"""File work at the edge: every read and write of skisnow's files lives in this package.

- :mod:`app.storage.textures`: height maps (``.npy``, ``.csv``) and shipped texture files.
- :mod:`app.storage.tables`: micro-scale lookup tables (HDF5) and their manifest.
- :mod:`app.storage.skis`: camber measurements (neutral CSV) and ski files (HDF5).
- :mod:`app.storage.common`: atomic writes, sha256, provenance attributes.
"""
