"""Built-in specimen and rig files."""
