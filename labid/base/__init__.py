"""labid/base."""
