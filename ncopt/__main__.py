"""``python -m ncopt``: the same command as ``ncopt`` (where the script folder is not on
PATH, as on many Windows installs)."""

from ncopt.cli.entry import main

main()
