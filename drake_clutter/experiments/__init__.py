"""Experiments of Sec. VI-B: specs and tiers (``tiers/``), work units, the SQLite store,
the executors (process pool, Ray) and the report (Tables III/IV, Fig. 9).

May import: everything below it (``common`` .. ``planners``, ``evaluation``); not ``viz``
or ``cli``.
"""
