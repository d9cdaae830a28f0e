"""`python -m avsim` is the `avsim` command."""

from avsim.cli import main

raise SystemExit(main())
