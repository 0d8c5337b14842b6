"""Traffic campaigns: random arrival-traffic scenarios (``mal-traffic``) planned in bulk (``mal-campaign``).

Modules: :mod:`.traffic` (+ :mod:`.traffic_cli`) generates scenarios; :mod:`.cli` is ``mal-campaign``;
:mod:`.runner` spreads the scenarios over a Dask cluster; :mod:`.isolation` runs each in a child process
(:mod:`.child`) with a time and memory limit; :mod:`.outcome` classifies a run into one of
:data:`mal_planner.errors.FAILURE_CLASSES`; :mod:`.metrics` computes the row's figures; :mod:`.results` is
the CSV table; :mod:`.summary` and :mod:`.figures` the report; :mod:`.plan_options` mirrors mal-plan's
options. No ROS imports.
"""
