#!/bin/sh
# Runs the regions step, then the shards, waiting for every one of each to complete, then the
# gather (Kubernetes has no dependency between Jobs: the wait is the dependency). Needs kubectl
# pointed at the cluster, the image crowd:latest (deploy/Dockerfile) and the volumes
# crowd-scene and crowd-shared.
set -eu
here="$(dirname "$0")"
kubectl delete job crowd-regions crowd-shards crowd-gather --ignore-not-found
kubectl apply -f "$here/regions.yaml"
kubectl wait --for=condition=complete job/crowd-regions --timeout=24h
kubectl apply -f "$here/shards.yaml"
kubectl wait --for=condition=complete job/crowd-shards --timeout=24h
kubectl apply -f "$here/gather.yaml"
kubectl wait --for=condition=complete job/crowd-gather --timeout=24h
