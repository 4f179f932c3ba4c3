"""Work surfaces beyond the flat panel (issue 33): a chart lays a design, measured in
millimetres on the skin, onto a curved surface, with its distortion measured.

* :mod:`~tattotronix.surface.chart`: the chart interface and its distortion;
* :mod:`~tattotronix.surface.cone`: the forearm phantom (a tapered elliptic cylinder),
  unrolled exactly;
* :mod:`~tattotronix.surface.mesh`: any triangle mesh from a file (a 3-D scan of a limb),
  checked, and charted by a least-squares conformal map around the placement;
* :mod:`~tattotronix.surface.setup`: the work surface of the ``surface`` settings, posed
  on the bench, and the design's placement on it.
"""
