"""Developer tools run on the project: the stages' code deps (``codedeps``), the
certification of the documents' figures (``certify``, the ``certify`` stage's), the
figures the documents cite (``docfigures``) and the tables derived from the CAD meshes
(``tables``). Nothing in the library imports them."""
