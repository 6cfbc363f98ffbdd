"""Diagnosis of measured traces: where the model is wrong, the cause, how sure, what is
ruled out (docs/diagnosis-method.md is the method).

A chain of stages on records (:mod:`.run`): :mod:`.prepare`, :mod:`.baseline` (with
:mod:`.basis`, :mod:`.slip_level`), :mod:`.selection` (with :mod:`.candidates`, and
:mod:`.criterion`: where an effect is judged), :mod:`.refit` (with :mod:`.level`,
:mod:`.sensed`), :mod:`.structure`, :mod:`.intervals`, :mod:`.detection`, :mod:`.coverage`
(caveats), :mod:`.result`. Each effect's knowledge is its policy
(:mod:`gms_comp.measured.policies`); its form is the runtime's catalogue.
"""
