"""Sequence metamodels of a building week: (batch, hours, inputs) -> (batch, hours, outputs).

Knows tensors and channel roles, never buildings, EnergyPlus or Gymnasium. The models (Transformer,
BiGRU, LSTM, ConvGRU, FFN), the paper's loss and the training loop land with the metamodels issue.
"""
