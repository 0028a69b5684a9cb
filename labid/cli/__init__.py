"""The headless command line: ``labid.cli.main`` (the door: parser, exit codes, failure lines),
``labid.cli.options`` (what every command shares), one module per command (``import_`` for
``labid import``, a keyword)."""
