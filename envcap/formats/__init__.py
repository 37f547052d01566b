"""File formats: KTX2, OpenEXR cube maps, PNG previews."""
