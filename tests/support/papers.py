"""The papers' published numbers the reproduction tests state, read from their one home
(docs/seed00X/paper.yaml, through :func:`adcs_sim.app.report.lead.paper_values`: what the reports
show beside ours)."""
from __future__ import annotations

from adcs_sim.app.report.lead import paper_values

# Seed 000: the three laws' runs of the UoSAT-12 wheel-failure case; per law, the paper's Table:
# (q4 within 1 ± 0.02, within 1 ± 0.01 (s after t0), ∫‖u‖dt after t0 (N m s)).
SEED000_LAWS = {'zero_momentum': 'uosat12_zero_momentum', 'snlc': 'uosat12_snlc', 'gsmn': 'uosat12_gsmn'}
SEED000_PAPER_KEYS = ('settling_q4_0.02_after_fault_s', 'settling_q4_0.01_after_fault_s',
                      'integrated_torque_after_fault_Nms')
SEED000_PAPER = {law: tuple(paper_values(name)[1][k] for k in SEED000_PAPER_KEYS) for law, name in SEED000_LAWS.items()}

# Seed 002: s, section 4.2 / Fig. 1 ("approximately 38 seconds").
SEED002_PAPER_SETTLING = paper_values('eseo_backstepping_slew')[1]['settling_eigenaxis_1deg_s']
