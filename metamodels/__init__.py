"""Sequence metamodels of a building week: (batch, hours, inputs) -> (batch, hours, outputs).

Knows tensors and channel roles, never buildings, EnergyPlus or Gymnasium: the models (Transformer, BiGRU,
LSTM, ConvGRU, FFN, :mod:`.models`), the paper's loss (:mod:`.loss`), the training loop (:mod:`.train`),
standardisation (:mod:`.normalisation`) and checkpoints (:mod:`.checkpoint`).
"""
