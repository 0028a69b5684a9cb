"""The lab panel: ``MainWindow`` with one module per view (setup, acquisition, modes,
waves, identification, gap). Views call the same workflow objects as the CLI."""
