"""Every figure of a run, in a fixed order: the branch diagram, the multipliers, the problem's
own figures, the tree of a bifurcation diagram and the orbit figures of ``output.orbits``;
drawn in two processes where that is possible (:mod:`nsm_continuation.figures.process`).
Importing this module does not import matplotlib: :func:`make_all` does when it draws, so a
run hands it to the writer and a child process without loading matplotlib here first."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from nsm_continuation.figures.process import in_two_processes

if TYPE_CHECKING:
    from nsm_continuation.runs.result import RunResult


def make_all(res: RunResult, out: Path) -> list[str]:
    """Every figure of a run written into ``out`` (the branch diagram, the multipliers against
    the diagram's horizontal quantity and in the complex plane, the problem's own figures, the
    bifurcation diagram of a tree, the orbit figures of ``output.orbits``,
    :mod:`nsm_continuation.figures.orbits`): their file names, in this order. Drawn in two
    processes where that is possible
    (:func:`nsm_continuation.figures.process.in_two_processes`)."""
    from nsm_continuation.figures import branches, multipliers, orbits, trees

    def branch_diagram() -> list[str]:
        if res.branches and any(br.points for br in res.branches):
            branches.fep(res, out / "fep.png")
            return ["fep.png"]
        return []

    def along() -> list[str]:
        name = multipliers.along_name(res)
        return [name] if multipliers.multipliers_along(res, out / name) else []

    def plane() -> list[str]:
        ok = multipliers.multipliers_plane(res, out / "multipliers_complex_plane.png")
        return ["multipliers_complex_plane.png"] if ok else []

    def problem_figures() -> list[str]:
        return list(res.problem.presentation.extra_plots(out, res.branches, res.window))

    def tree() -> list[str]:
        if res.case.output.axes is None and not res.tree:
            return []
        return ["diagram.png"] if trees.figure(res, out / "diagram.png") else []

    def orbit_figures() -> list[str]:
        if res.case.output.orbits is None:
            return []
        return orbits.make_figures(res, out)

    return in_two_processes([branch_diagram, along, plane, problem_figures, tree,
                             orbit_figures])
