"""Everything that crosses the network: Zenoh sessions and their configuration, the messages and
their validation, the peers' poses, the lab router and its certificates."""
