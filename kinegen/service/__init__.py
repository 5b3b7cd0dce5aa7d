"""The work behind kinegen's commands, as functions that return reports.

Each command's work comes in two steps: ``plan`` reads the model and its generated module through
a :class:`kinegen.api.Session` and checks the request against the model; ``run`` computes and
returns a report. A request the model cannot answer raises :class:`kinegen.errors.RequestError`
naming the command line's option it concerns. Nothing here prints or writes a file: the command
line (:mod:`kinegen.cli`) formats the reports.

* :mod:`kinegen.service.solve` -- ``kinegen solve``: the motion, the forces, the pumps' flows;
* :mod:`kinegen.service.cycle` -- ``kinegen cycle``: the fastest timing of a case's path;
* :mod:`kinegen.service.envelope` -- ``kinegen envelope``: the working range, its boundary and
  its figures' sensitivities;
* :mod:`kinegen.service.inspection` -- ``kinegen inspect``: Phi_q's exact rank, null spaces and
  determinant at one configuration, and what kind of singularity it has;
* :mod:`kinegen.service.study` -- ``kinegen optimize``: a design study optimized on exact (or
  finite-difference) gradients;
* :mod:`kinegen.service.charts` -- ``kinegen forces`` and ``kinegen lift``: the ISO 6015 tool
  forces, force maps and the ISO 10567 lift chart.
"""
