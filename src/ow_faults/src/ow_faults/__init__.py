"""ow_faults: OceanWATERS' fault injection (dynamic_reconfigure ``/faults``) and fault detection.

Pure cores: :mod:`ow_faults.injection` (the fault set, its validation, power profiles) and
:mod:`ow_faults.detection` (the detection rules). Node modules: ``faults_node``, ``detector_node``.
"""
