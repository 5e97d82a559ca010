"""sweeps: config-driven sweep runner and the flocksweep CLI."""
