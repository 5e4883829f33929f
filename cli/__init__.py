"""rangekit command-line interface (installed as the ``rangekit_cli`` package)."""
