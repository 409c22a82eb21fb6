"""LinuxCNC as a controller (Debian linuxcnc-uspace): a headless instance with a generated
one-joint config (`process`), its axis commanded over linuxcncrsh's TCP text protocol (`axis`),
and a simulated laser that reads the joint's motor position, compensation included, from HAL
(`motor`). docs/linuxcnc.md says why linuxcncrsh and what is simulated."""
