"""Numerical solvers that know nothing of robots: iLQR over small dynamics and cost
protocols, pure NumPy.

May import: ``common`` only; never pydrake (a test checks it).
"""
