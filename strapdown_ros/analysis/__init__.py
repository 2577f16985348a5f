"""Analysis of recordings against a model: the discrepancy workflow (:mod:`.discrepancy`), its
increment pairs (:mod:`.pairs`), linear-Gaussian residual model (:mod:`.linear_model`) and
residual diagnostics (:mod:`.diagnostics`).  No ROS imports."""
