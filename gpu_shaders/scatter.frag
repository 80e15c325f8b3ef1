// Each sample adds one; the target blends with ONE, ONE (additive).
void main()
{
  ow_count = 1.0;
}
