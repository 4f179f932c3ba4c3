"""Developer tools: not imported by the library."""
