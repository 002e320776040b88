"""The grasp database: schema and migrations, the store holding every SQL
statement of the project (its reads in ``store``; its writes, columns, rows
and one-line failures in ``writing``, ``columns``, ``rows``, ``failures``),
the ranking rule, the writer lock."""
