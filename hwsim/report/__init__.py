"""Human reports of run folders, trades and sweep databases: ``report.md`` and a
self-contained ``report.html`` (:mod:`hwsim.report.report`).  Render outputs themselves
(``stats.json``, images, CSVs) are :mod:`hwsim.run.output`."""
