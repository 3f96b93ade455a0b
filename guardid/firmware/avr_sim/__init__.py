"""The AVR port (``firmware_proto/avr``) as built for the MCU, run in simavr on the simulated
plant (``firmware=avr``), its robot constants generated from the YAML, and its cycle budget."""
