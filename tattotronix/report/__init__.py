"""Reports on the pipeline: figures, the drawing animation, the robot stage's report, and
certification of the docs."""
