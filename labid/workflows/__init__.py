"""labid/workflows."""
