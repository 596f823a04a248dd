/* A library planted in a compiled-library cache (tests/test_cache_trust.py,
   tests/test_cache_integrity.py): its constructor runs when the dynamic loader opens
   it and creates the file named by $SOFTCURVE_TEST_MARKER. Built with -DSYMBOL=name,
   the one function it defines. */
#include <stdio.h>
#include <stdlib.h>

__attribute__((constructor)) static void planted(void)
{
    const char *marker = getenv("SOFTCURVE_TEST_MARKER");
    FILE *file = marker ? fopen(marker, "w") : NULL;
    if (file) {
        fclose(file);
    }
}

__attribute__((visibility("default"))) int SYMBOL(void)
{
    return 7;
}
