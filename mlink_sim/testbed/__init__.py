"""Testbeds: docker-compose generation (:mod:`.compose`), a Docker Swarm stack (:mod:`.stack`) and Kubernetes
manifests (:mod:`.k8s`) placed on a cluster (:mod:`.placement`), and multi-host runs in Linux network namespaces
(:mod:`.netns`, ``scripts/netns-testbed``). See docs/testbeds.md."""

from .compose import compose_document, render_compose

__all__ = ["compose_document", "render_compose"]
