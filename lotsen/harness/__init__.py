"""The closed loop on simulated time: the simulated boat, its sensors, the estimator, the
supervisor and the controllers, assembled by `lotsen.stack.launch.build_stack` and run on a
`SimExecutor` — deterministic and faster than real time. Missions (`mission`), the fault suite
(`fault_injection`) and the estimator evaluation (`estimator`) are built on it; the algorithms
below never import the simulator, only this package and the stack do."""
