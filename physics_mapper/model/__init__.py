"""The scene model (ROS-free, no physics engine): what the world holds and what perception says of it.

Poses and every quaternion computation (``geometry``), weighted hypotheses ranked for the search
(``hypotheses``), shapes, bodies, search parameters, scenes and problems (``scene``), their YAML
files read and validated into one clear error (``scene_files``, ``yaml_files``, ``errors``) and
loaded in a thread a signal does not wait for (``scene_loading``), mesh
files and their convex decomposition with its cache (``meshes``, ``decomposition``, ``bullet``),
``package://`` URLs and the shipped files (``resources``, ``shipped``), and the caps on input sizes
(``limits``). Imports no other room.
"""
