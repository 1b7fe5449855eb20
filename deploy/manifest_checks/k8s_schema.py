"""The subset of the Kubernetes API schema these manifests use: field names per object, the
kinds and their apiVersions. A field not listed is reported (as kubectl's strict field
validation would)."""

import re

DNS_LABEL = re.compile(r"^[a-z0-9]([-a-z0-9]*[a-z0-9])?$")

# Field names per object, from the Kubernetes API reference (v1.29). Only the objects these
# manifests use are checked field by field; the rest are checked by the cross-reference rules.
OBJECT_META = {"name", "namespace", "labels", "annotations", "generateName", "finalizers",
               "ownerReferences"}
DEPLOYMENT_SPEC = {"replicas", "selector", "template", "strategy", "minReadySeconds",
                   "revisionHistoryLimit", "paused", "progressDeadlineSeconds"}
POD_SPEC = {"volumes", "initContainers", "containers", "ephemeralContainers", "restartPolicy",
            "terminationGracePeriodSeconds", "activeDeadlineSeconds", "dnsPolicy",
            "nodeSelector", "serviceAccountName", "serviceAccount",
            "automountServiceAccountToken", "nodeName", "hostNetwork", "hostPID", "hostIPC",
            "shareProcessNamespace", "securityContext", "imagePullSecrets", "hostname",
            "subdomain", "affinity", "schedulerName", "tolerations", "hostAliases",
            "priorityClassName", "priority", "dnsConfig", "readinessGates", "runtimeClassName",
            "enableServiceLinks", "preemptionPolicy", "overhead", "topologySpreadConstraints",
            "setHostnameAsFQDN", "os", "hostUsers", "schedulingGates", "resourceClaims"}
CONTAINER = {"name", "image", "command", "args", "workingDir", "ports", "envFrom", "env",
             "resources", "resizePolicy", "restartPolicy", "volumeMounts", "volumeDevices",
             "livenessProbe", "readinessProbe", "startupProbe", "lifecycle",
             "terminationMessagePath", "terminationMessagePolicy", "imagePullPolicy",
             "securityContext", "stdin", "stdinOnce", "tty"}
CONTAINER_PORT = {"name", "hostPort", "containerPort", "protocol", "hostIP"}
PROBE = {"exec", "httpGet", "tcpSocket", "grpc", "initialDelaySeconds", "timeoutSeconds",
         "periodSeconds", "successThreshold", "failureThreshold",
         "terminationGracePeriodSeconds"}
PROBE_HANDLERS = {"exec", "httpGet", "tcpSocket", "grpc"}
GRPC_ACTION = {"port", "service"}
SECURITY_CONTEXT = {"capabilities", "privileged", "seLinuxOptions", "windowsOptions",
                    "runAsUser", "runAsGroup", "runAsNonRoot", "readOnlyRootFilesystem",
                    "allowPrivilegeEscalation", "procMount", "seccompProfile",
                    "appArmorProfile"}
POD_SECURITY_CONTEXT = {"seLinuxOptions", "windowsOptions", "runAsUser", "runAsGroup",
                        "runAsNonRoot", "supplementalGroups", "supplementalGroupsPolicy",
                        "fsGroup", "sysctls", "fsGroupChangePolicy", "seccompProfile",
                        "appArmorProfile", "seLinuxChangePolicy"}
RESOURCES = {"requests", "limits", "claims"}
VOLUME_MOUNT = {"name", "readOnly", "recursiveReadOnly", "mountPath", "subPath",
                "mountPropagation", "subPathExpr"}
VOLUME_SOURCES = {"emptyDir", "persistentVolumeClaim", "configMap", "secret", "hostPath",
                  "projected", "downwardAPI", "ephemeral", "csi", "nfs", "iscsi", "image",
                  "awsElasticBlockStore", "gcePersistentDisk", "azureDisk", "azureFile",
                  "cephfs", "cinder", "fc", "flexVolume", "flocker", "gitRepo", "glusterfs",
                  "photonPersistentDisk", "portworxVolume", "quobyte", "rbd", "scaleIO",
                  "storageos", "vsphereVolume"}
SERVICE_SPEC = {"ports", "selector", "clusterIP", "clusterIPs", "type", "externalIPs",
                "sessionAffinity", "loadBalancerIP", "loadBalancerSourceRanges", "externalName",
                "externalTrafficPolicy", "healthCheckNodePort", "publishNotReadyAddresses",
                "sessionAffinityConfig", "ipFamilies", "ipFamilyPolicy",
                "allocateLoadBalancerNodePorts", "loadBalancerClass", "internalTrafficPolicy",
                "trafficDistribution"}
SERVICE_PORT = {"name", "protocol", "appProtocol", "port", "targetPort", "nodePort"}
PVC_SPEC = {"accessModes", "selector", "resources", "volumeName", "storageClassName",
            "volumeMode", "dataSource", "dataSourceRef", "volumeAttributesClassName"}
ACCESS_MODES = {"ReadWriteOnce", "ReadOnlyMany", "ReadWriteMany", "ReadWriteOncePod"}
KUSTOMIZATION = {"apiVersion", "kind", "resources", "images", "labels", "commonLabels",
                 "commonAnnotations", "namespace", "namePrefix", "nameSuffix", "patches",
                 "configMapGenerator", "secretGenerator", "generatorOptions", "replicas",
                 "components"}
PDB_SPEC = {"minAvailable", "maxUnavailable", "selector", "unhealthyPodEvictionPolicy"}
ENV_SOURCES = {"configMapKeyRef", "secretKeyRef", "fieldRef", "resourceFieldRef"}
KINDS = {"ConfigMap": "v1", "Service": "v1", "PersistentVolumeClaim": "v1",
         "Secret": "v1", "Deployment": "apps/v1", "PodDisruptionBudget": "policy/v1"}
SECRET = {"apiVersion", "kind", "metadata", "type", "data", "stringData", "immutable"}
