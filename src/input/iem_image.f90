!> Netpbm images (PBM and PGM, plain and binary: P1, P2, P4, P5) read strictly, for cell maps
!> drawn in a paint program (issue 10, first part): one pixel a cell, the first row the top
!> of the body. A malformed file gives a message naming what is wrong, never a guess.
module iem_image
  use iem_kinds, only: i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: image_t, parse_image, read_image, max_image_pixels

  !> Most pixels an image may have (cells of a cell map; the node limit is 2^31-1).
  integer, parameter :: max_image_pixels = 2000000000

  !> A decoded image: pix(column, row), row 1 at the top; values 0..maxval. For PBM (P1,
  !> P4) maxval is 1 and 1 is black, as in the format.
  type :: image_t
    integer :: width = 0, height = 0, maxval = 0
    integer, allocatable :: pix(:, :)
  end type image_t

contains

  !> Read and decode the image file path; stat /= 0 with msg (naming the file) on failure.
  subroutine read_image(path, img, stat, msg)
    character(len=*), intent(in) :: path
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: bytes
    character(len=256) :: iom
    integer :: unit, ios
    integer(i8) :: n
    stat = 1
    open(newunit=unit, file=path, access='stream', form='unformatted', status='old', &
         action='read', iostat=ios, iomsg=iom)
    if (ios /= 0) then
      msg = "image '"//path//"': cannot be opened ("//trim(iom)//')'
      return
    end if
    inquire(unit=unit, size=n)
    ! a P5 raster of 16-bit pixels holds 2 bytes a pixel; the header is short
    if (n < 0 .or. n > 2_i8*max_image_pixels + 65536_i8) then
      msg = "image '"//path//"': its size cannot be read or is beyond any image iem takes"
      close(unit)
      return
    end if
    allocate(character(len=n) :: bytes, stat=ios)
    if (ios == 0 .and. n > 0) read(unit, iostat=ios, iomsg=iom) bytes
    close(unit)
    if (ios /= 0) then
      msg = "image '"//path//"': cannot be read ("//trim(iom)//')'
      return
    end if
    call parse_image(bytes, img, stat, msg)
    if (stat /= 0) msg = "image '"//path//"': "//msg
  end subroutine read_image

  !> Decode the bytes of a PBM or PGM file; stat /= 0 with msg on anything malformed.
  subroutine parse_image(bytes, img, stat, msg)
    character(len=*), intent(in) :: bytes
    type(image_t), intent(out) :: img
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: pos, kind, v, i, j, need, ierr
    logical :: bits
    stat = 1
    msg = ''
    if (len(bytes) < 2) then
      msg = 'not a PBM or PGM file (too short)'
      return
    end if
    if (bytes(1:1) /= 'P' .or. index('1245', bytes(2:2)) == 0) then
      msg = 'not a PBM or PGM file (it must start with P1, P2, P4 or P5)'
      return
    end if
    kind = iachar(bytes(2:2)) - iachar('0')
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
    allocate(img%pix(img%width, img%height), stat=ierr)
    if (ierr /= 0) then
      msg = 'out of memory for '//itoa(img%width)//' x '//itoa(img%height)//' pixels'
      return
    end if
    select case (kind)
    case (1, 2)
      rows: do j = 1, img%height
        do i = 1, img%width
          if (kind == 1) then
            call skip_blanks()
            if (pos > len(bytes)) exit rows
            v = index('01', bytes(pos:pos)) - 1
            if (v < 0) then
              msg = 'pixel ('//itoa(i)//', '//itoa(j)//'): a PBM pixel must be 0 or 1'
              return
            end if
            pos = pos + 1
          else
            call body_number(v, i, j)
            if (len(msg) > 0) return
          end if
          img%pix(i, j) = v
        end do
      end do rows
      call skip_blanks()
      if (pos <= len(bytes) .or. j <= img%height) then
        if (j <= img%height) then
          msg = 'the pixels end before row '//itoa(j)//' of '//itoa(img%height)
        else
          msg = 'text after the last pixel'
        end if
        return
      end if
    case (4, 5)
      ! exactly one whitespace byte after the header, then the raster
      pos = pos + 1
      if (kind == 4) then
        need = ((img%width + 7)/8)*img%height
      else
        need = img%width*img%height*merge(2, 1, img%maxval > 255)
      end if
      if (len(bytes) - pos + 1 /= need) then
        msg = 'the raster holds '//itoa(max(len(bytes) - pos + 1, 0))//' bytes; '// &
              itoa(img%width)//' x '//itoa(img%height)//' needs '//itoa(need)
        return
      end if
      do j = 1, img%height
        do i = 1, img%width
          if (kind == 4) then
            v = iachar(bytes(pos + (j - 1)*((img%width + 7)/8) + (i - 1)/8: &
                             pos + (j - 1)*((img%width + 7)/8) + (i - 1)/8))
            img%pix(i, j) = merge(1, 0, btest(v, 7 - mod(i - 1, 8)))
          else if (img%maxval > 255) then
            v = pos + 2*((j - 1)*img%width + i - 1)
            img%pix(i, j) = 256*iachar(bytes(v:v)) + iachar(bytes(v + 1:v + 1))
          else
            v = pos + (j - 1)*img%width + i - 1
            img%pix(i, j) = iachar(bytes(v:v))
          end if
        end do
      end do
    end select
    if (any(img%pix > img%maxval)) then
      msg = 'a pixel exceeds maxval '//itoa(img%maxval)
      return
    end if
    stat = 0

  contains

    !> Skip whitespace and, in the header, comments from '#' to the end of the line.
    subroutine skip_blanks(comments)
      logical, intent(in), optional :: comments
      logical :: c
      c = .false.
      if (present(comments)) c = comments
      do while (pos <= len(bytes))
        if (c .and. bytes(pos:pos) == '#') then
          do while (pos <= len(bytes))
            if (bytes(pos:pos) == achar(10) .or. bytes(pos:pos) == achar(13)) exit
            pos = pos + 1
          end do
        else if (index(' '//achar(9)//achar(10)//achar(13)//achar(11)//achar(12), &
                       bytes(pos:pos)) == 0) then
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
      do while (pos <= len(bytes))
        d = iachar(bytes(pos:pos)) - iachar('0')
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
      if (pos <= len(bytes)) then
        if (index(' #'//achar(9)//achar(10)//achar(13)//achar(11)//achar(12), &
                  bytes(pos:pos)) == 0) ok = .false.
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
  end subroutine parse_image
end module iem_image
