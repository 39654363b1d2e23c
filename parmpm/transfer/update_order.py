"""The update orders (Nairn 2003; Buzzi et al. 2008) and the three G2P modes they are made of.

USL: one G2P pass updating velocity, position, ``L``, ``F`` and stress (:data:`G2P_USL`).
MUSL: a motion pass (velocity and the position increment, :data:`G2P_MUSL_MOTION`), the
momentum re-mapped to the grid, then a deformation pass (``L``, ``F``, stress and the position,
:data:`G2P_MUSL_DEFORM`). Every G2P kernel, generic or specialised, takes one of these codes.
"""
G2P_USL, G2P_MUSL_MOTION, G2P_MUSL_DEFORM = 0, 1, 2

#: the ``method.update`` names
UPDATES = ("usl", "musl")
