"""City probe sets: sharded bakes (in one process or on Dask), resumable and bit-identical, with
a top-down street map; see ``docs/scale.md``."""
