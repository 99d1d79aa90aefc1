"""Frame and wheel sources: the simulated site, UVC/file cameras, serial wheels, remote push."""
