"""The jobs room: background work of the catalogue, persisted in its database.

- :mod:`.runner` — :class:`JobRunner` claims and runs jobs (leases, heartbeats, take-over);
- :mod:`.handlers` — the job kinds of the catalogue (grind table, ski network) and their
  clean-up, one place for the service processes and ``skisnow worker``.

May import: ``service``, ``training``, ``storage``, :mod:`skisnow.solvers` and the shared
top-level modules of ``app``. Never ``api``, ``web`` or ``commands``.
"""

from skisnow.app.jobs.runner import JobContext, JobInterrupted, JobLeaseLost, JobRunner

__all__ = ["JobContext", "JobInterrupted", "JobLeaseLost", "JobRunner"]
