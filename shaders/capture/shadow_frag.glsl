#version 430
// Sun shadow map: depth only, no color output.
void main() {}
