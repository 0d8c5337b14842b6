"""A Cyclone DDS configuration that keeps discovery and traffic on loopback (127.0.0.1).

Used by ``mal-launch`` when CYCLONEDDS_URI is not set (the main job never touches the network) and by
the integration tests (each with its own ROS_DOMAIN_ID).
"""

from __future__ import annotations

from pathlib import Path

LOOPBACK_XML = """<?xml version="1.0" encoding="UTF-8"?>
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <General>
      <Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
      <AllowMulticast>false</AllowMulticast>
    </General>
    <Discovery>
      <ParticipantIndex>auto</ParticipantIndex>
      <MaxAutoParticipantIndex>40</MaxAutoParticipantIndex>
      <Peers><Peer address="127.0.0.1"/></Peers>
    </Discovery>
  </Domain>
</CycloneDDS>
"""


def write_loopback_config(path: Path) -> str:
    """Write the configuration to ``path``; return the value for CYCLONEDDS_URI."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(LOOPBACK_XML, encoding="utf-8")
    return path.resolve().as_uri()
