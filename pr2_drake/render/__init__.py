"""Photo-realistic renders of an episode: ``pr2-drake render`` and ``pr2-drake bench render``.

An episode is re-simulated as ``pr2-drake run`` runs it (:mod:`.resim`), its plant state kept
at the requested times; a render rig (:mod:`.rig`) poses a copy of its testbed at each state.
One scene description, read from Drake's SceneGraph (:mod:`.scene`, :mod:`.meshes`), feeds
the path tracer, Blender's Cycles on the CPU (:mod:`.cycles`, the ``[photoreal]`` extra),
while Drake's VTK raster draws the same camera for comparison and gives exact depth and
labels (:mod:`.frames`). Light: the testbed's sun and sky map (:mod:`.light`); settings in
``models/textures/path_tracing.yaml`` (:mod:`.settings`).
"""

INSTALL_HINT = ("the path tracer needs Blender's Cycles (the bpy wheel, Python 3.11): "
                "pip install 'pr2-drake[photoreal]'")
"""What to install for the path tracer: the one line ``pr2-drake render`` prints without it."""
