"""`python -m irloc`, the same as the `irloc` command."""

from irloc.cli import main

raise SystemExit(main())
