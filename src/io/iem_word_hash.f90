!> The word hash of checkpoint files: a hash of each 8-byte word and its index in the file,
!> XORed over words into a checksum that does not depend on who hashed which words
!> (iem_checkpoint), and chained over characters into a hash of a text (the model and the
!> record layout a checkpoint belongs to).
module iem_word_hash
  use iem_kinds, only: i8
  implicit none
  private
  public :: word_hash, words_hash, records_hash, text_hash

  !> Low 32 bits; the seed of the high lane.
  integer(i8), parameter :: mask32 = 4294967295_i8, seed32 = 2654435769_i8

contains

  !> The hash of word w at word index i of the file: two 32-bit lanes mixed with murmur3's
  !> finaliser, seeded by the index; one-to-one in w, so a change of any one word always
  !> changes the checksum. Integer arithmetic stays below 2**63 (no overflow).
  elemental integer(i8) function word_hash(i, w) result(z)
    integer(i8), intent(in) :: i, w
    integer(i8) :: a, b
    a = fmix32(ieor(iand(w, mask32), fmix32(iand(i + 1, mask32))))
    b = fmix32(ieor(ieor(shiftr(w, 32), fmix32(iand(shiftr(i, 32) + seed32, mask32))), a))
    z = ior(shiftl(b, 32), fmix32(ieor(a, b)))
  end function word_hash

  !> murmur3's 32-bit finaliser of h (0 <= h < 2**32).
  elemental integer(i8) function fmix32(h) result(x)
    integer(i8), intent(in) :: h
    x = ieor(h, shiftr(h, 16))
    x = mul32(x, 2246822507_i8)
    x = ieor(x, shiftr(x, 13))
    x = mul32(x, 3266489909_i8)
    x = ieor(x, shiftr(x, 16))
  end function fmix32

  !> x*c modulo 2**32 for 0 <= x, c < 2**32, in 16-bit halves of c.
  elemental integer(i8) function mul32(x, c)
    integer(i8), intent(in) :: x, c
    mul32 = iand(x*iand(c, 65535_i8) + shiftl(iand(x*shiftr(c, 16), 65535_i8), 16), mask32)
  end function mul32

  !> XOR of the hashes of the words v(1:) stored from word index first on.
  pure integer(i8) function words_hash(first, v) result(x)
    integer(i8), intent(in) :: first, v(:)
    integer :: j
    x = 0
    do j = 1, size(v)
      x = ieor(x, word_hash(first + j - 1, v(j)))
    end do
  end function words_hash

  !> XOR of the hashes of the records rec(:, k) of n words stored at global indices gids(k)
  !> of the record array that starts at word index first.
  pure integer(i8) function records_hash(first, n, gids, rec) result(x)
    integer(i8), intent(in) :: first, gids(:)
    integer, intent(in) :: n
    integer(i8), intent(in) :: rec(:, :)
    integer(i8) :: base
    integer :: j, k
    x = 0
    do k = 1, size(gids)
      base = first + gids(k)*n
      do j = 1, n
        x = ieor(x, word_hash(base + j - 1, rec(j, k)))
      end do
    end do
  end function records_hash

  !> A 64-bit hash of a text (the word hash chained over its characters).
  pure integer(i8) function text_hash(text) result(x)
    character(len=*), intent(in) :: text
    integer :: k
    x = 0
    do k = 1, len(text)
      x = word_hash(int(k, i8), ieor(x, int(iachar(text(k:k)), i8)))
    end do
  end function text_hash
end module iem_word_hash
