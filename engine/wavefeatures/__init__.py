"""engine/wavefeatures."""
