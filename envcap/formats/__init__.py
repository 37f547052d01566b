"""File formats (KTX2, OpenEXR cube maps, PNG previews) and the probe-set output writers that use them."""
