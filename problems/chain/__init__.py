"""The N-dof linear chain with one dof impacting a rigid wall, e = 1.

Legrand, Junca, Heng (2017), *Nonsmooth modal analysis of a N-degree-of-freedom system undergoing
a purely elastic impact law* (``../shared/papers/000_dbd673a68ec5508d.txt``):

* :mod:`.ndof_impact`: the problem ``ndof_impact`` (T-parametrised fixed points of the first
  return map), composed from
* :mod:`.parameters`: the YAML schema (chain, matrices, gap, starts) and the sizing of a run;
* :mod:`.modal`: the modal model (2.9)-(2.11);
* :mod:`.closed_form`: closed-form orbits (4.1)-(4.2), (5.4), (7.1) and the poles and roots of
  ``w_N`` (3.1);
* :mod:`.admissibility`: Definition 2.2 from the closed form;
* :mod:`.stability`: the linearised return map (3.5)/(A.8), Floquet multipliers, Krein
  signatures;
* :mod:`.starts`: starts, continuation bounds and preflight;
* :mod:`.presentation`: frequency-energy plots (Fig. 3.2), ``w_N`` (Fig. 3.1), orbits, report;
* :mod:`.simulate`: an event-driven simulation, the oracle of the closed form;
* :mod:`.trig_sum`: exact extrema of a sum of sinusoids (the admissibility test).
"""
