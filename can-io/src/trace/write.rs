//! Writers of the text trace formats (`dnet-master --log FILE --format F`) (to be written).
