"""Layouts of a mesh in the plane: the paper's MDS (Eq. 11-14), conformal (LSCM) and Tutte layouts.

``mds``        classical MDS, landmark MDS, SMACOF stress majorization (Eq. 1)
``conformal``  LSCM, the conformal reference layout, orientation
``tutte``      the disk with holes fanned, Tutte's embedding
"""
