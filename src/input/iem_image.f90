!> Netpbm images (PBM and PGM, plain and binary: P1, P2, P4, P5) read strictly, for cell maps
!> drawn in a paint program (issue 10, first part): one pixel a cell, the first row the top
!> of the body. A malformed file gives a message naming what is wrong, never a guess.
!>
!> A band of rows can be read alone (read_image_rows), in memory O(width x rows of the band)
!> plus a read buffer of 1 MiB (iem_image_bytes), never the whole file, so that each rank of
!> a distributed set-up reads only the rows it needs. What a band read checks:
!> - always the header (format, width, height, maxval);
!> - binary files (P4, P5): the file's exact size against the header, whatever the band (a
!>   truncated or over-long file is refused by every band); then only the band's bytes are
!>   read (seek), so a bad pixel (above maxval) outside the band is not seen;
!> - plain files (P1, P2): every row from the first down to the band's last is parsed and
!>   checked (the rows above the band are read in chunks and dropped); the rows below the
!>   band are not read, except that a band asked up to the last row or beyond (last_row >=
!>   height) also checks that nothing but whitespace follows the last pixel.
!> A band that is empty (after clipping to 1..height) reads only the header (and, binary,
!> checks the size). The contract for callers: the union of the bands read by the ranks
!> validates the whole file, so every rank's bands together must cover rows 1..height, the
!> last band asked with last_row >= height; the message a rank gets names the first fault
!> it met (row and column of a pixel, or the byte counts of a raster).
module iem_image
  use iem_kinds, only: i8
  use iem_strings, only: itoa
  use iem_image_bytes, only: image_bytes_t
  implicit none
  private
  public :: image_t, parse_image, read_image, read_image_rows, max_image_pixels

  !> Most pixels an image may have (cells of a cell map; the node limit is 2^31-1).
  integer, parameter :: max_image_pixels = 2000000000

  !> A decoded image, or a band of its rows: width, height and maxval are the whole
  !> image's; pix(column, row) holds rows first_row..last_row only, allocated with those
  !> bounds (pix(1:width, first_row:last_row); row 1 at the top), so pix(i, j) is pixel
  !> (column i, row j) of the file whichever band was read. A whole image has first_row = 1,
  !> last_row = height; an empty band has last_row = first_row - 1 and pix of shape (width, 0)
  !> (whose lbound is then 1, as for any zero-size dimension). Values 0..maxval; for
  !> PBM (P1, P4) maxval is 1 and 1 is black, as in the format. A band may also be narrowed
  !> to columns first_col..last_col (pix(first_col:last_col, first_row:last_row); all
  !> columns by default).
  type :: image_t
    integer :: width = 0, height = 0, maxval = 0
    integer :: first_row = 1, last_row = 0, first_col = 1, last_col = 0
    integer, allocatable :: pix(:, :)
  end type image_t

contains

  !> Read and decode the whole image file path; stat /= 0 with msg (naming the file) on
  !> failure.
  subroutine read_image(path, img, stat, msg)
    character(len=*), intent(in) :: path
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    call read_image_rows(path, 1, huge(1), img, stat, msg)
  end subroutine read_image

  !> Read rows first_row..last_row (1 = top) of the image file path, clipped to 1..height (an
  !> empty band allowed), into img%pix(:, img%first_row:img%last_row), checking what the
  !> module's header says; with first_col, last_col only those columns (clipped to
  !> 1..width) are kept (a binary file's other columns are not read). stat /= 0 with msg
  !> (naming the file) and no pix on failure.
  subroutine read_image_rows(path, first_row, last_row, img, stat, msg, first_col, last_col)
    character(len=*), intent(in) :: path
    integer, intent(in) :: first_row, last_row
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer, intent(in), optional :: first_col, last_col
    type(image_bytes_t) :: src
    character(len=256) :: iom
    integer :: unit, ios, c0, c1
    integer(i8) :: n
    stat = 1
    open(newunit=unit, file=path, access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      msg = "image '"//path//"': cannot be opened ("//trim(iom)//')'
      return
    end if
    inquire(unit=unit, size=n)
    if (n < 0) then
      msg = "image '"//path//"': its size cannot be read"
      close(unit)
      return
    end if
    call src%attach_file(unit, n)
    c0 = 1
    c1 = huge(1)
    if (present(first_col)) c0 = first_col
    if (present(last_col)) c1 = last_col
    call decode(src, first_row, last_row, img, stat, msg, c0, c1)
    close(unit)
    if (src%ios /= 0) then
      stat = 1
      msg = 'cannot be read ('//trim(src%iom)//')'
    end if
    if (stat /= 0) then
      msg = "image '"//path//"': "//msg
      if (allocated(img%pix)) deallocate(img%pix)
    end if
  end subroutine read_image_rows

  !> Decode the bytes of a whole PBM or PGM file; stat /= 0 with msg on anything malformed.
  subroutine parse_image(bytes, img, stat, msg)
    character(len=*), intent(in) :: bytes
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(image_bytes_t) :: src
    call src%attach_string(bytes)
    call decode(src, 1, huge(1), img, stat, msg, 1, huge(1))
  end subroutine parse_image

  !> Decode rows first_row..last_row, columns first_col..last_col of the PBM or PGM file
  !> served by src (as the module's header says); stat /= 0 with msg on anything malformed.
  subroutine decode(src, first_row, last_row, img, stat, msg, first_col, last_col)
    type(image_bytes_t), intent(inout) :: src
    integer, intent(in) :: first_row, last_row, first_col, last_col
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer(i8) :: pos, row_bytes, need, p
    integer :: kind, v, i, j, ierr, f, l, c0, c1
    logical :: bits
    character(len=2) :: magic
    stat = 1
    msg = ''
    if (src%n < 2) then
      msg = 'not a PBM or PGM file (too short)'
      return
    end if
    magic = byte(1_i8)
    magic(2:2) = byte(2_i8)
    if (magic(1:1) /= 'P' .or. index('1245', magic(2:2)) == 0) then
      msg = 'not a PBM or PGM file (it must start with P1, P2, P4 or P5)'
      return
    end if
    kind = iachar(magic(2:2)) - iachar('0')
    bits = kind == 1 .or. kind == 4
    pos = 3
    call header_number(img%width, 'width')
    if (len(msg) > 0) return
    call header_number(img%height, 'height')
    if (len(msg) > 0) return
    img%maxval = 1
    if (.not. bits) then
      call header_number(img%maxval, 'maxval')
      if (len(msg) > 0) return
      if (img%maxval < 1 .or. img%maxval > 65535) then
        msg = 'maxval '//itoa(img%maxval)//' must be in 1..65535'
        return
      end if
    end if
    if (img%width < 1 .or. img%height < 1) then
      msg = 'width and height must be >= 1 (got '//itoa(img%width)//' x '// &
            itoa(img%height)//')'
      return
    end if
    if (real(img%width)*real(img%height) > real(max_image_pixels)) then
      msg = itoa(img%width)//' x '//itoa(img%height)//' pixels: more than '// &
            itoa(max_image_pixels)
      return
    end if
    ! the band, clipped to the image; an empty one keeps last = first - 1
    f = max(first_row, 1)
    l = min(last_row, img%height)
    if (l < f) l = f - 1
    img%first_row = f
    img%last_row = l
    c0 = max(first_col, 1)
    c1 = min(last_col, img%width)
    if (c1 < c0) c1 = c0 - 1
    img%first_col = c0
    img%last_col = c1
    allocate(img%pix(c0:c1, f:l), stat=ierr)
    if (ierr /= 0) then
      msg = 'out of memory for '//itoa(c1 - c0 + 1)//' x '//itoa(l - f + 1)//' pixels'
      return
    end if
    select case (kind)
    case (1, 2)
      if (l < f) then
        stat = 0
        return
      end if
      ! every row down to the band's last is checked; those above the band are dropped
      rows: do j = 1, l
        do i = 1, img%width
          if (kind == 1) then
            call skip_blanks()
            if (pos > src%n) exit rows
            v = index('01', byte(pos)) - 1
            if (v < 0) then
              msg = 'pixel ('//itoa(i)//', '//itoa(j)//'): a PBM pixel must be 0 or 1'
              return
            end if
            pos = pos + 1
          else
            call body_number(v, i, j)
            if (len(msg) > 0) return
            if (v > img%maxval) then
              call above_maxval(v, i, j)
              return
            end if
          end if
          if (j >= f .and. i >= c0 .and. i <= c1) img%pix(i, j) = v
        end do
      end do rows
      if (j <= l) then
        msg = 'the pixels end before row '//itoa(j)//' of '//itoa(img%height)
        return
      end if
      if (last_row >= img%height) then
        call skip_blanks()
        if (pos <= src%n) then
          msg = 'text after the last pixel'
          return
        end if
      end if
    case (4, 5)
      ! exactly one whitespace byte after the header, then the raster
      pos = pos + 1
      if (kind == 4) then
        row_bytes = (img%width + 7)/8
      else
        row_bytes = int(img%width, i8)*merge(2, 1, img%maxval > 255)
      end if
      need = row_bytes*img%height
      if (src%n - pos + 1 /= need) then
        msg = 'the raster holds '//itoa(max(src%n - pos + 1, 0_i8))//' bytes; '// &
              itoa(img%width)//' x '//itoa(img%height)//' needs '//itoa(need)
        return
      end if
      ! only the band's bytes are read: the buffer starts at the band's first byte
      do j = f, l
        p = pos + (j - 1)*row_bytes
        do i = c0, c1
          if (kind == 4) then
            v = iachar(byte(p + (i - 1)/8))
            v = merge(1, 0, btest(v, 7 - mod(i - 1, 8)))
          else if (img%maxval > 255) then
            v = 256*iachar(byte(p + 2*(i - 1)))
            v = v + iachar(byte(p + 2*(i - 1) + 1))
          else
            v = iachar(byte(p + i - 1))
          end if
          if (v > img%maxval) then
            call above_maxval(v, i, j)
            return
          end if
          img%pix(i, j) = v
        end do
      end do
    end select
    stat = 0

  contains

    !> The byte at p: from the buffer when it holds p (the common case, kept inline), else
    !> through src%at.
    function byte(p) result(c)
      integer(i8), intent(in) :: p
      character(len=1) :: c
      if (p > src%base .and. p <= src%base + src%have) then
        c = src%buf(p - src%base:p - src%base)
      else
        c = src%at(p)
      end if
    end function byte

    !> The message for pixel (i, j) of value v above maxval.
    subroutine above_maxval(v, i, j)
      integer, intent(in) :: v, i, j
      msg = 'pixel ('//itoa(i)//', '//itoa(j)//'): '//itoa(v)//' exceeds maxval '// &
            itoa(img%maxval)
    end subroutine above_maxval

    !> Skip whitespace and, in the header, comments from '#' to the end of the line.
    subroutine skip_blanks(comments)
      logical, intent(in), optional :: comments
      logical :: c
      character(len=1) :: ch
      c = .false.
      if (present(comments)) c = comments
      do while (pos <= src%n)
        ch = byte(pos)
        if (c .and. ch == '#') then
          do while (pos <= src%n)
            ch = byte(pos)
            if (ch == achar(10) .or. ch == achar(13)) exit
            pos = pos + 1
          end do
        else if (index(' '//achar(9)//achar(10)//achar(13)//achar(11)//achar(12), ch) == 0) then
          return
        end if
        pos = pos + 1
      end do
    end subroutine skip_blanks

    !> A decimal number at pos (no sign), into n; msg when there is none or it overflows.
    subroutine read_number(n, ok)
      integer, intent(out) :: n
      logical, intent(out) :: ok
      integer :: d
      n = 0
      ok = .false.
      do while (pos <= src%n)
        d = iachar(byte(pos)) - iachar('0')
        if (d < 0 .or. d > 9) exit
        if (n > (huge(n) - d)/10) then
          ok = .false.
          return
        end if
        n = 10*n + d
        ok = .true.
        pos = pos + 1
      end do
      ! a number ends at whitespace, a comment or the end of the file
      if (pos <= src%n) then
        if (index(' #'//achar(9)//achar(10)//achar(13)//achar(11)//achar(12), &
                  byte(pos)) == 0) ok = .false.
      end if
    end subroutine read_number

    subroutine header_number(n, what)
      integer, intent(out) :: n
      character(len=*), intent(in) :: what
      logical :: ok
      call skip_blanks(.true.)
      call read_number(n, ok)
      if (.not. ok) msg = 'the header has no valid '//what
    end subroutine header_number

    subroutine body_number(n, i, j)
      integer, intent(out) :: n
      integer, intent(in) :: i, j
      logical :: ok
      call skip_blanks()
      call read_number(n, ok)
      if (.not. ok) msg = 'pixel ('//itoa(i)//', '//itoa(j)//'): not a number, or missing'
    end subroutine body_number
  end subroutine decode
end module iem_image
