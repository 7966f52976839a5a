"""The N-dof linear chain with one dof impacting a rigid wall, e = 1.

Legrand, Junca, Heng (2017), *Nonsmooth modal analysis of a N-degree-of-freedom system undergoing
a purely elastic impact law* (``../shared/papers/000_dbd673a68ec5508d.txt``):

* :mod:`.ndof_impact`: the problem ``ndof_impact`` (T-parametrised fixed points of the first
  return map, frequency-energy plots, admissibility, stability of the linearised return map) and
  its figures;
* :mod:`.trig_sum`: exact extrema of a sum of sinusoids (the admissibility test).
"""
