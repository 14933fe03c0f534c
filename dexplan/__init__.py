"""dexplan: dexterous in-hand manipulation planning in the n-finger grasp subspace.

After Saut, Sahbani and Perdereau, "A Global Approach for Dexterous Manipulation
Planning Using Paths in n-fingers Grasp Subspace" (ICARCV 2006).
"""

from __future__ import annotations

from dexplan.exceptions import DexplanError

__version__ = "0.1.0"

__all__ = ["DexplanError", "__version__"]
