"""The board's wiring as the twin sees it (firmware/src/board/mod.rs's pin table): which
pins are the machine's outputs, which inputs the scenario drives, and their levels when
the machine is healthy and at rest."""

AXES = ("x", "y", "z")

# outputs: name -> (port, pin); "high" means energised / enabled / released
ENABLE = {"x": ("D", 0), "y": ("D", 1), "z": ("D", 2)}
BRAKE = {"x": ("D", 4), "y": ("D", 5), "z": ("D", 6)}
DIRECTION = {"x": ("E", 10), "y": ("E", 12), "z": ("E", 14)}
# TIM1 CH1..CH3 on PE9 / PE11 / PE13, AF1
PWM = {"x": ("E", 9, 0), "y": ("E", 11, 1), "z": ("E", 13, 2)}
LED_ENABLED, LED_FAULT = ("D", 12), ("D", 14)

# inputs and their healthy levels (NC contacts to GND: low = healthy)
ESTOP = ("B", 12)  # TIM1_BKIN, AF1: high = stop
LIMITS = {
    "x-": ("C", 0), "x+": ("C", 1), "y-": ("C", 2), "y+": ("C", 3), "z-": ("C", 4), "z+": ("C", 5),
}
AMP_FAULT = {"x": ("D", 8), "y": ("D", 9), "z": ("D", 10)}
ARM_BUTTON = ("D", 3)  # NO to GND: low = pressed
INDEX = {"x": ("B", 10), "y": ("B", 1), "z": ("B", 0)}

HEALTHY_INPUTS = (
    [(ESTOP, 0)]
    + [(p, 0) for p in LIMITS.values()]
    + [(p, 0) for p in AMP_FAULT.values()]
    + [(ARM_BUTTON, 1)]
    + [(p, 0) for p in INDEX.values()]
)

# alternate functions that take a pin into a timer's input: (port, pin, af) -> (timer,
# channel 0..3): the index inputs' input capture (TIM2_CH3 on PB10, TIM3_CH3 on PB0)
AF_INPUTS = {
    ("B", 10, 1): ("TIM2", 2),
    ("B", 0, 2): ("TIM3", 2),
}

# encoder timers per axis
ENCODER_TIMER = {"x": "TIM2", "y": "TIM5", "z": "TIM3"}

# alternate functions that drive a pin: (port, pin, af) -> signal
AF_OUTPUTS = {
    ("E", 9, 1): ("TIM1", 0),
    ("E", 11, 1): ("TIM1", 1),
    ("E", 13, 1): ("TIM1", 2),
    ("A", 2, 7): ("USART2_TX", None),
}
