"""External physics behind lotsen's plant interface: ArduPilot SITL's JSON protocol (lotsen plays
ArduPilot's side), the channel map of `extra.physics`, and the reference server that serves
lotsen's own simulated boat (docs/physics.md). The drivers' layer: it does I/O (UDP sockets);
`lotsen.sim` stays pure.

    lotsen.physics.config    the `extra.physics` section and the channel map (light: the config
                             loader imports it before `lotsen run` takes its lock)
    lotsen.physics.protocol  servo packets and state lines as bytes (pure)
    lotsen.physics.client    UdpPhysics: an external physics as a `lotsen.sim.Plant`
    lotsen.physics.server    PhysicsServer: a plant served over the protocol (`lotsen physics-server`)
"""

from lotsen.physics.config import ACTUATORS, ChannelMap, PhysicsConfig, parse_address

__all__ = ["ACTUATORS", "ChannelMap", "PhysicsConfig", "parse_address"]
