"""MeshLab-style filters built on the geoshape library (see plugins/README)."""
