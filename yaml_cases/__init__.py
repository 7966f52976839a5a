"""The bundled cases (installed as ``nsm_continuation.yaml_cases``): the YAML files of this
folder and of ``restart/``, run by name (``nsm-continuation run ndof_fig3_2_fep``,
``nsm.run("ndof_fig3_2_fep")``) and listed by ``nsm-continuation cases``
(:mod:`nsm_continuation.cases.bundled`). No code: this file makes the folder a package whose
data the wheel ships."""
