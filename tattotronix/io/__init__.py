"""Reading and writing what the stages make: atomic outputs, provenance and artifacts.

This layer sits just above ``tattotronix.errors`` and knows nothing of the robot, the
path or the controller: the domain modules hand it arrays and plain values.
"""
