"""engine/identify."""
