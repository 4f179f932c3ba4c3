"""The job server: the arm run from a browser or a script (``tattotronix serve``).

A thin shell over the application layer (:mod:`tattotronix.app`): a drawing is planned
with :func:`tattotronix.plan` (or :func:`tattotronix.plan_strokes`), and a job plays a plan
on the arm (a dry run unless the real arm is asked for and confirmed) in a process of its
own (:mod:`~tattotronix.server.runner`), which the server starts, pauses (the arm lifts the
needle at its next frame), resumes and stops, and follows through the arm's state file.

* :mod:`~tattotronix.server.auth`: the access token a network bind needs;
* :mod:`~tattotronix.server.plans`: uploads checked and stored, plans made and kept;
* :mod:`~tattotronix.server.jobs`: the one job at a time, its process and its state;
* :mod:`~tattotronix.server.runner`: the job's process;
* :mod:`~tattotronix.server.web`: the routes (FastAPI), documented as OpenAPI;
* :mod:`~tattotronix.server.cli`: ``tattotronix serve``.
"""
