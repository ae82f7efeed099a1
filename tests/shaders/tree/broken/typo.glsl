// A helper with a compile error on line 3.
float helper() {
    return undeclaredThing;
}
