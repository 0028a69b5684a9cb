"""``python -m labid.cli COMMAND ...``."""
from .main import main

raise SystemExit(main())
