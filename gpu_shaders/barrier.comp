// An empty dispatch: Blender's gpu module ends each dispatch with a memory barrier, and
// has no other way to ask for one (shaders.BARRIER_PROGRAM).
void main()
{
}
