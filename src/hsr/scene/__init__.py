"""What is drawn and from where: meshes, instances, cameras, built-in scenes, and files in
and out (OBJ/MTL and trimesh formats, textures, image and buffer writers)."""
