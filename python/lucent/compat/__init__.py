"""Drop-in layers: ``lucent.compat.open3d.RaycastingScene`` (Open3D's ray casting) and
``lucent.compat.trimesh.RayMeshIntersector`` (trimesh's ``mesh.ray``)."""
