"""Presentation shared by the bar's two problems (the WFEM lattice, ``wfem_bar``, and its
continuum limit, ``bar_continuum``): the frequency-energy plot of the paper's figures, in
``omega / omega_1`` (eq. 13) and ``E / E_ref`` (eq. 14), with the CSV and report columns of
earlier releases."""

from __future__ import annotations

from typing import ClassVar


class BarFrequencyEnergy:
    """Mixin placed before :class:`~nsm_continuation.core.problem.Problem` in a bar problem's
    bases: it overrides the protocol's presentation defaults."""

    energy_quantity: ClassVar[str | None] = "energy_ratio"
    fep_axes = ("omega_ratio", "energy_ratio")
    fep_labels = (r"$\omega/\omega_1$", r"energy $E/E_{ref}$ (eq. 14)")
    diagram_title: ClassVar[str] = "Frequency-energy plot"
    diagram_yscale: ClassVar[str] = "log"
    csv_head = ["T", "omega", "energy"]
    event_columns = ["omega", "T", "energy"]
