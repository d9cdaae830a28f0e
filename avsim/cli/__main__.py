"""`python -m avsim.cli` is the `avsim` command, as `python -m avsim` is."""

from avsim.cli.command import main

raise SystemExit(main())
