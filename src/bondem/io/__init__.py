"""Input and output: results (HDF5), checkpoints, ParaView (VTK), CSV files."""
