"""The board twin: the release firmware ELF (`cargo fw`) on an emulated STM32F407.
docs/board-twin.md says what is modelled, the cycle model, and what only a board shows."""
