# The man pages shapematch(1) and shapematchd(8), written by docs/man/man.sh
# from the programs' --help, which print their option tables (the one
# source of --help, the man pages and the docs' parameter table); release
# only (`make install` installs them).
build/release/man/shapematch.1 build/release/man/shapematchd.8 &: docs/man/man.sh \
    build/release/shapematch build/release/shapematchd
	$(call show,GEN,$@)docs/man/man.sh build/release build/release/man $(VERSION)
RELEASE_ONLY_TARGETS += man/shapematch.1 man/shapematchd.8
