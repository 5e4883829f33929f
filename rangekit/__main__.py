"""``python -m rangekit``: the command-line interface."""

from rangekit_cli.main import main

main()
