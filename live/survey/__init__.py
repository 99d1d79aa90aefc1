"""The live survey: blinks, the drive's observations and the solver worker."""
