"""The atlas algorithms: a mesh of any topology cut into disk charts, each with a bijective layout, packed.

The stage that runs them on a mesh, flattening each chart with the pipeline, is ``heatparam.pipeline.atlas_stage``
(``pipeline.parameterize`` makes an atlas of what a single flattening refuses). No module here imports the pipeline.

- ``repair``: lossless repair of scan-like input into clean components (:func:`~heatparam.atlas.repair.repair`).
- ``chart_topology``: a component's adjacency (``Topology``) and a chart's own mesh (``chart_mesh``).
- ``grow``: normal-cone region growing from farthest-point seeds, regions that are disks.
- ``flatten``: quick flattenings of many charts in one LSCM solve and their bijectivity checks.
- ``stretches``: the common border of two charts split into stretches that end at cone points.
- ``merge``: merging charts while the merged layout stays bijective and within the bound.
- ``segment``: grow, check, split and merge: the charts of one component.
- ``polish``: the charts polished together (``refine.charts``) from their checked layouts.
- ``chart_seams``: the seams between the charts of an atlas, and their lengths.
- ``overlap``: exact count of overlapping UV triangle pairs. ``pack``: packing the charts without overlap.
"""
