# Sourced by the device scripts beside it: the Vulkan loader from the .debs in .gl/ (device
# README), and the runtime directory wgpu's Vulkan instance wants.
for f in .gl/*.deb; do [ -e "$f" ] && dpkg -x "$f" /; done
ldconfig
export XDG_RUNTIME_DIR=${XDG_RUNTIME_DIR:-/tmp}
