"""rosbag2-compatible MCAP bags: writing (crash-tolerant), reading (no ROS needed), repair.

One module per job (import what you need from the module that has it):

* :mod:`adcs_sim.bag.writer`  — :class:`BagWriter` writes a bag folder (``<name>_0.mcap`` +
  ``metadata.yaml``), as ``ros2 bag record -s mcap`` does; ``qos_dicts``, ``cdr_stamp_ns``.
* :mod:`adcs_sim.bag.reader`  — ``read_raw`` / ``read_messages`` / ``read_metadata``: the messages
  and metadata of any rosbag2 bag (MCAP complete or truncated, sqlite3), one at a time;
  ``is_complete``.
* :mod:`adcs_sim.bag.batches` — ``ColumnReader``: one streaming pass yielding the raw CDR bytes of
  selected topics in large ``TopicBatch`` es (the fast path of ``adcs-analyze``).
* :mod:`adcs_sim.bag.columns` — ``decode_batch`` / ``decode_diagnostics``: a batch's CDR bytes to
  numpy columns, without deserialising message by message.
* :mod:`adcs_sim.bag.records` — ``McapRecords``: the checked record-by-record walk of one MCAP file
  every reader above uses (chunk, data-section and summary CRCs, framing, bounded lengths); where
  a damaged file's intact part ends (``Damage``) and ``BagDamaged``, the readers' error.
* :mod:`adcs_sim.bag.repair`  — ``repair``: rewrite the intact part of a killed writer's or a
  damaged bag into a complete one, saying what was kept and dropped.
* :mod:`adcs_sim.bag.lock`    — ``BagLock``: one writer at a time (the writer's lock, naming it);
  ``bag_writer``: who writes a bag now; ``BagInUse``.
* :mod:`adcs_sim.bag.storage` — ``bag_files`` (which files hold a bag, MCAP or other rosbag2
  storage), ``mcap_file``, ``typestore`` (the ROS 2 Jazzy type store).
* :mod:`adcs_sim.bag.schema`  — the recorder's parameter schema.
"""
