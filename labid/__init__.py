"""labid package."""
