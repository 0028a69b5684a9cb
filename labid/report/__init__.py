"""labid/report."""
