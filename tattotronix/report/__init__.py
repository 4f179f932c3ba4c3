"""Reports on the pipeline: figures, the drawing animation, and certification of the docs."""
