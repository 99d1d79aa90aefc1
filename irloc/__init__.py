"""irloc: the `irloc` command-line entry point."""
