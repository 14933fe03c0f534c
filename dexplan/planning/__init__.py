"""Planning in the grasp subspace: OMPL adapter, GSn space, samplers, roadmaps.

:mod:`dexplan.planning.ompl_adapter` is the only module of dexplan that imports
``ompl``; the other planning modules hand it plain NumPy callables.
"""
