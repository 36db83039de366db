"""Helpers shared by the test modules (no test module imports another; they all import from here).

* :mod:`support.paths`: the repository's folders (``ROOT``, ``CONFIG``, ``BAGS``, ``SCRIPTS``);
* :mod:`support.scenarios`: scenario files and batches (``make_scenario``, ``write_campaign``,
  ``batch_of``, ``batch_run_data``);
* :mod:`support.comparison`: recorded run == computed run, published vs ours (``assert_recorded_run_equal``,
  ``reference_comparison``, ``plain_message``);
* :mod:`support.processes`: processes through /proc (``children``, ``alive``, ``kill_tree``, ``Spawner``);
* :mod:`support.bags`: bags being written (``states_on_disk``) and synthetic bags of any writer;
* :mod:`support.report_runs`: the report tests' synthetic runs (``write_bag``, ``RUNS``);
* :mod:`support.plant_cases`, :mod:`support.inverse_optimal`, :mod:`support.papers`,
  :mod:`support.packaging`, :mod:`support.reference_pd`, :mod:`support.estimation_truth`,
  :mod:`support.edge_paths`: the inputs and independent references of one subject each;
* :mod:`support.ros_wheels`: which modules are the ROS wheels' (and a finder that refuses them);
* needing ROS (rclpy or the message packages): :mod:`support.ros_graph` (in-process graphs,
  ``refused``), :mod:`support.recorder`, :mod:`support.recorded_topics`, :mod:`support.rogue`.

Every other module here imports without the ROS wheels (``tests/test_suite_layout.py`` checks it).
``support/scripts/`` holds the programs tests run as subprocesses (by path, or on ``PYTHONPATH``).
"""
