"""The report layouts of the project, one module each; :mod:`radar2shape.reporting.registry` registers
them by name. A grid names one (``report: table1``) and ``radar2shape report --grid NAME`` writes it.
"""
