"""Robot programs a controller can run, from any plan: URScript, ABB RAPID and KUKA KRL (docs/programs.md).

- :mod:`~sprayplan.programs.build`: the plan as moves (runs, approaches and retracts, speeds, blends, gun
  events), the same for every format;
- :mod:`~sprayplan.programs.urscript`, :mod:`~sprayplan.programs.rapid`, :mod:`~sprayplan.programs.krl`: each
  format's writer and its strict reader (an unknown statement is an error);
- :mod:`~sprayplan.programs.stage`: the export stage (``sprayplan export``, ``sprayplan plan --program``):
  files written all or nothing with a ``summary.json``;
- :mod:`~sprayplan.programs.check` and :mod:`~sprayplan.programs.film`: programs read back and compared with
  the plan, move by move and by the film they leave.
"""
