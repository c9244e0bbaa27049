"""Layouts of a mesh in the plane: the paper's MDS (Eq. 11-14), conformal (LSCM), Tutte and projected layouts.

``mds``        classical MDS, landmark MDS, SMACOF stress majorization (Eq. 1)
``conformal``  LSCM, the conformal reference layout, orientation
``tutte``      the disk with holes fanned, Tutte's embedding
``projection`` the orthogonal projection onto the mean plane (a start for height-field-like parts)
"""
